"""The unit table: factors, spellings, refusals."""

from __future__ import annotations

import pytest

from hil.contract.units import canonical, convert, factor
from hil.errors import ConfigError


def test_factors_of_the_units_a_controller_uses() -> None:
    assert factor("g/s", "kg/h") == pytest.approx(3.6)
    assert factor("km/h", "m/s") == pytest.approx(1 / 3.6)
    assert factor("kg/hm2", "kg/ha") == 1.0
    assert factor("mV", "V") == pytest.approx(1e-3)
    assert convert(30.0, "m", "mm") == pytest.approx(30000.0)


def test_spellings_are_one_unit() -> None:
    assert factor("kg / ha", "kg/hm²") == 1.0
    assert canonical("kg/hm²") == "kg/hm2"
    assert canonical("r/min") == "rpm"


@pytest.mark.parametrize(("a", "b"), [("g/s", "m/s"), ("mV", "mm"), ("kg/ha", "g/s")])
def test_units_of_different_dimensions_do_not_convert(a: str, b: str) -> None:
    with pytest.raises(ConfigError, match="cannot convert"):
        factor(a, b)


def test_an_unknown_unit_is_named() -> None:
    with pytest.raises(ConfigError, match="furlong"):
        canonical("furlong/fortnight")
