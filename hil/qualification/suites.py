"""The suites of a qualification: their names, which ones ``--hil-suite`` selects, and which
suite can judge which DUT.

Every suite test carries a ``hil_suite(name)`` marker; a test of a suite that was not selected
is deselected, and a rig test whose suite gives the set-point in a way the DUT does not take
(an ISOBUS implement's suite for a DUT that is not one, or the reverse) is skipped with the
reason.
"""

from __future__ import annotations

from hil.dut.profile import DutProfile
from hil.errors import ConfigError

SUITES = ("fast", "full", "robustness", "busload", "isobus")
#: the suite of ISOBUS implements ([wiring] isobus = true): field runs under the rig's Task
#: Controller; the other suites give the set-point by the rig's own frames
ISOBUS_SUITE = "isobus"


def wanted_suites(option: str) -> set[str]:
    """The suites a comma-separated ``--hil-suite`` value names (``all``: every one).

    Raises
    ------
    ConfigError
        A name is no suite, or none is given.
    """
    names = {n.strip() for n in option.split(",") if n.strip()}
    if "all" in names:
        return set(SUITES)
    unknown = names - set(SUITES)
    if unknown or not names:
        raise ConfigError(f"unknown suite {', '.join(sorted(unknown))!s}; "
                          f"choose from {', '.join(SUITES)}, all")
    return names


def interface_mismatch(suite: str, profile: DutProfile) -> str:
    """Why a rig test of ``suite`` cannot judge the DUT of ``profile`` ("" if it can)."""
    if profile.wiring.isobus and suite != ISOBUS_SUITE:
        return (f"a {suite} test gives the set-point by the rig's own frames; the DUT "
                f"{profile.name} is an ISOBUS implement (its suite: {ISOBUS_SUITE})")
    if suite == ISOBUS_SUITE and not profile.wiring.isobus:
        return (f"an {ISOBUS_SUITE} test (a field run under the rig's Task Controller); the "
                f"DUT {profile.name} is not an ISOBUS implement ([wiring] isobus = false)")
    return ""
