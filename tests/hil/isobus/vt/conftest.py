"""The VT operator fixture (``vt_operator``) for the tests that provide a ``vt_bench``."""

from hil.isobus.vt.testing import vt_operator

__all__ = ["vt_operator"]
