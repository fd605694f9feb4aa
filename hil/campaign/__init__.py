"""Statistical qualification: Monte-Carlo campaigns of the qualification suites.

A *sample* is the chosen suites run once at seed ``S+i`` with rig parameters drawn from a
dispersion file (:mod:`hil.campaign.dispersion`), in a private temporary directory and a fresh
pytest process (:mod:`hil.campaign.sample`). Dask distributed spreads the samples over the
workers of a ``LocalCluster`` or of any cluster by address (:mod:`hil.campaign.engine`); the
statistics (:mod:`hil.campaign.stats`) turn them into a pass rate with an exact confidence
interval and a verdict, written as ``campaign.json`` (:mod:`hil.campaign.record`).
"""

from hil.campaign.dispersion import Dispersion, Distribution, load_dispersion
from hil.campaign.overrides import format_override, parse_overrides
from hil.campaign.stats import clopper_pearson, lower_bound, samples_needed

__all__ = [
    "Dispersion",
    "Distribution",
    "clopper_pearson",
    "format_override",
    "load_dispersion",
    "lower_bound",
    "parse_overrides",
    "samples_needed",
]
