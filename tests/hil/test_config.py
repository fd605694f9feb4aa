from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import pytest

from hil.config import from_mapping, load_toml
from hil.errors import ConfigError


@dataclass(frozen=True)
class Wiring:
    node_id: int
    database: str


@dataclass(frozen=True)
class Profile:
    name: str
    period_s: float
    clock: Literal["realtime", "lockstep"] = "lockstep"
    gains: tuple[float, ...] = ()
    wiring: Wiring | None = None
    extra: dict[str, int] | None = None


def test_builds_nested_dataclasses_and_converts_ints_to_floats() -> None:
    p = from_mapping(Profile, {"name": "x", "period_s": 1, "gains": [1, 2.5],
                               "wiring": {"node_id": 5, "database": "a.dbc"}})
    assert p.period_s == 1.0 and isinstance(p.period_s, float)
    assert p.gains == (1.0, 2.5)
    assert p.wiring == Wiring(5, "a.dbc")


@pytest.mark.parametrize(("data", "key", "fragment"), [
    ({"name": "x", "period_s": 1, "perod": 2}, "perod", "unknown key"),
    ({"period_s": 1}, "name", "missing required key"),
    ({"name": "x", "period_s": "fast"}, "period_s", "expected a number"),
    ({"name": "x", "period_s": 1, "clock": "sundial"}, "clock", "not one of"),
    ({"name": "x", "period_s": 1, "gains": [1, "a"]}, "gains[1]", "expected a number"),
    ({"name": "x", "period_s": 1, "wiring": {"node_id": 1.5, "database": "d"}},
     "wiring.node_id", "expected an integer"),
    ({"name": "x", "period_s": 1, "wiring": {"node_id": 1, "database": "d", "bus": 1}},
     "wiring.bus", "unknown key"),
    ({"name": "x", "period_s": True}, "period_s", "expected a number"),
])
def test_errors_name_the_key(data: dict, key: str, fragment: str) -> None:
    with pytest.raises(ConfigError) as err:
        from_mapping(Profile, data, path="p.toml")
    assert err.value.key == key
    assert f"p.toml: [{key}]" in str(err.value)
    assert fragment in str(err.value)


def test_load_toml_names_the_file(tmp_path: Path) -> None:
    path = tmp_path / "bad.toml"
    path.write_text('name = "x"\nperiod_s = 0.1\n[wiring]\nnode_id = 3\ndatabase = "d"\nx = 1\n')
    with pytest.raises(ConfigError, match=r"bad\.toml: \[wiring\.x\] unknown key"):
        load_toml(path, Profile)
    path.write_text("name = \n")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_toml(path, Profile)
    with pytest.raises(ConfigError, match="file not found"):
        load_toml(tmp_path / "missing.toml", Profile)


def test_config_error_is_a_value_error() -> None:
    assert issubclass(ConfigError, ValueError)
