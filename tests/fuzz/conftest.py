"""Hypothesis settings for the fuzz tests.

The default run uses the ``agrihil-fast`` profile (a few dozen examples per property, a fixed
seed derivation so a failure reproduces); ``HYPOTHESIS_PROFILE=agrihil-long`` runs hundreds
per property (``python -m pytest tests/fuzz -p no:randomly``, ~minutes). Tests marked
``fuzz_long`` (deselected by the default run through ``-m "not slow"``? no: they are also
marked ``slow``) run the CLI in separate processes.
"""

from __future__ import annotations

import os

from hypothesis import HealthCheck, settings

settings.register_profile(
    "agrihil-fast", max_examples=25, deadline=None, derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
    database=None)
settings.register_profile(
    "agrihil-long", max_examples=400, deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "agrihil-fast"))
