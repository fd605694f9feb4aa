"""The device qualification report: ``report.html`` of a ``hil qualify`` directory.

>>> from hil.report import write_html   # write_html(Path("out")) -> Path("out/report.html")
"""

from hil.report.page import REPORT_NAME, render, write_html
from hil.report.record import QualRecord, ReportError, load_qualification

__all__ = ["REPORT_NAME", "QualRecord", "ReportError", "load_qualification", "render",
           "write_html"]
