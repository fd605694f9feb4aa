"""Hypothesis fuzz of the DDOP parser: it never crashes, and every error names where it is."""

from hypothesis import given, settings
from hypothesis import strategies as st

from hil.isobus.ddop import DdopError, DdopParseError, ObjectPool, parse_pool, problems
from hil.isobus.ddop.samples import section_control_pool

SAMPLE = section_control_pool(sections=3).to_bytes()
FUZZ = settings(max_examples=120, deadline=None, derandomize=True, database=None)


@st.composite
def _mutated_pool(draw: st.DrawFn) -> bytes:
    data = bytearray(SAMPLE)
    for _ in range(draw(st.integers(1, 6))):
        kind = draw(st.sampled_from(["flip", "cut", "insert", "delete"]))
        pos = draw(st.integers(0, max(len(data) - 1, 0)))
        if kind == "flip" and data:
            data[pos] = draw(st.integers(0, 255))
        elif kind == "cut":
            del data[pos:]
        elif kind == "insert":
            data[pos:pos] = draw(st.binary(min_size=1, max_size=8))
        elif data:
            del data[pos:pos + draw(st.integers(1, 8))]
    return bytes(data)


def _parse_and_validate(data: bytes, version: int) -> None:
    try:
        objects = parse_pool(data, version=version)
    except DdopParseError as err:
        assert err.offset is not None and 0 <= err.offset <= len(data)
        assert str(err).startswith("DDOP")
        return
    for problem in problems(objects, version=version):
        assert isinstance(problem, DdopError)
        assert problem.reason
        if problem.object_id is not None:
            assert str(problem).startswith(f"DDOP object {problem.object_id}: ")
    if not problems(objects, version=version):
        assert ObjectPool(objects, version).to_bytes() == data


@FUZZ
@given(data=st.binary(max_size=400), version=st.sampled_from([3, 4]))
def test_random_bytes_never_crash_the_parser(data: bytes, version: int) -> None:
    _parse_and_validate(data, version)


@FUZZ
@given(data=_mutated_pool(), version=st.sampled_from([3, 4]))
def test_mutated_pools_never_crash_and_errors_name_an_object(data: bytes, version: int) -> None:
    _parse_and_validate(data, version)


@FUZZ
@given(data=_mutated_pool())
def test_whatever_parses_serialises_back_to_the_same_bytes(data: bytes) -> None:
    try:
        objects = parse_pool(data)
    except DdopParseError:
        return
    again = ObjectPool(objects).to_bytes()
    # exact except a float32 NaN scale, whose payload Python's float may not keep
    if again != data:
        assert any(getattr(o, "scale", 0.0) != getattr(o, "scale", 0.0) for o in objects)
