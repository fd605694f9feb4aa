"""Every numeric profile key of :data:`hil.validation.PROFILE_RANGES`: a value out of its range
is refused naming the file and the key, the bounds themselves (when closed) are accepted
(issue 30: ``ready_timeout_s = 1e308`` and ``heartbeat_period_ms = 1e300`` passed)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from hil.dut.profile import load_profile
from hil.errors import ConfigError
from hil.validation import PROFILE_RANGES, Range

ROOT = Path(__file__).resolve().parents[2]
PROFILE = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-daemon.toml"


def _with(tmp: Path, key: str, value: str) -> Path:
    table, name = key.split(".")
    text = PROFILE.read_text()
    if re.search(rf"^{name} = ", text, flags=re.M):
        text = re.sub(rf"^{name} = .*$", f"{name} = {value}", text, flags=re.M)
    else:
        text = text.replace(f"[{table}]\n", f"[{table}]\n{name} = {value}\n", 1)
    path = tmp / PROFILE.name          # a profile's name must be its file's
    path.write_text(text)
    return path


def _outside(rng: Range) -> st.SearchStrategy[str]:
    """Values ``rng`` refuses, as TOML text (integers for an integer key)."""
    if rng.kind == "int":
        low, high = int(rng.low or 0), int(rng.high or 0)
        return (st.integers(min_value=-(2**62), max_value=low - 1)
                | st.integers(min_value=high + 1, max_value=2**62)).map(str)
    below = (st.floats(max_value=rng.low, allow_nan=False, allow_infinity=False,
                       exclude_max=not rng.low_open) if rng.low is not None else st.nothing())
    above = (st.floats(min_value=rng.high, allow_nan=False, allow_infinity=False,
                       exclude_min=not rng.high_open) if rng.high is not None else st.nothing())
    return (below | above).map(repr)


@given(data=st.data())
def test_out_of_range_keys_are_refused_naming_the_key(
        data: st.DataObject, tmp_path_factory: pytest.TempPathFactory) -> None:
    key = data.draw(st.sampled_from(sorted(PROFILE_RANGES)))
    rng = PROFILE_RANGES[key]
    text = data.draw(_outside(rng))
    path = _with(tmp_path_factory.mktemp("p"), key, text)
    with pytest.raises(ConfigError) as caught:
        load_profile(path)
    message = str(caught.value)
    assert str(path) in message and f"{key.split('.')[1]} must be" in message, message


def test_the_unchanged_profile_loads(tmp_path: Path) -> None:
    """So that a refusal above is the range's, not the copy's."""
    load_profile(_with(tmp_path, "timing.heartbeat_period_ms", "100"))


@pytest.mark.parametrize("key", sorted(PROFILE_RANGES))
def test_closed_bounds_are_accepted(tmp_path: Path, key: str) -> None:
    rng = PROFILE_RANGES[key]
    for bound, is_open in ((rng.low, rng.low_open), (rng.high, rng.high_open)):
        if bound is None or is_open or (key == "timing.control_period_ms"):
            continue          # the control period must also equal the rig's SYNC period
        value = str(int(bound)) if rng.kind == "int" else repr(float(bound))
        load_profile(_with(tmp_path, key, value))
