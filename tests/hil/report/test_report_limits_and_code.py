"""The report shows where each of the profile's limits stands against the catalogue's
default (a loosened one with its reason), and the code under test (issue 43)."""

from __future__ import annotations

from hil.dut.profile import Limit
from hil.effective_limits import RecordedLimit, origin_of, record_limits
from hil.report.markup import esc
from hil.report.sections_head import code_items
from hil.report.sections_tables import profile_limits_table


def test_the_record_limits_table_says_how_each_entry_departs_from_the_default() -> None:
    table = record_limits({
        "depth.field.pass_rate": Limit(low=85.0, reason="stony plot"),
        "depth.step.overshoot": Limit(high=8.0),
        "depth.field.cv": Limit(high=6.0),
        "depth.step.response_time": Limit(high=3.0, marginal=0.2),
        "depth.step.true_steady_state_error": Limit(when=({"to_mm": 20, "high": 4.0},),
                                                    reason="shallow sensor bias"),
    })
    assert table["depth.field.pass_rate"] == {
        "low": 85.0, "high": None, "unit": "%", "origin": "loosened", "default": ">= 90",
        "source": "GB/T 20865-2007 band, [D] Table 3", "reason": "stony plot"}
    assert table["depth.step.overshoot"]["origin"] == "tightened"
    assert table["depth.field.cv"]["origin"] == "set"
    assert table["depth.step.response_time"]["origin"] == "default"
    case = table["depth.step.true_steady_state_error"]
    assert case["origin"] == "loosened" and case["when"][0]["conditions"] == {"to_mm": 20}
    # read back as the report does, the same verdict
    for name, entry in table.items():
        assert origin_of(name, RecordedLimit.parse(entry)) == entry["origin"], name


def test_the_report_shows_a_loosened_limit_with_its_reason() -> None:
    html = profile_limits_table(record_limits({
        "depth.field.pass_rate": Limit(low=85.0, reason="stony plot <3 km>"),
        "depth.step.overshoot": Limit(high=8.0)}))
    assert "2 of the profile; 1 looser than the catalogue's default" in html
    assert "loosened (default &gt;= 90)" in html and esc("stony plot <3 km>") in html
    assert "tightened (default &lt;= 10)" in html
    assert "from GB/T 20865-2007 band, [D] Table 3" in html
    # a record written before the table carried origins: computed from the catalogue
    old = {"depth.field.pass_rate": {"low": 85.0, "high": None, "unit": "%"}}
    assert "(not recorded: see the profile)" in profile_limits_table(old)
    assert "every measurement is judged by the catalogue" in profile_limits_table({})


def test_the_device_block_names_the_code_under_test() -> None:
    items = dict(code_items({
        "program": {"path": "reference_controllers/daemon.py", "sha256": "a" * 64,
                    "bytes": 10, "what": "module reference_controllers.daemon"},
        "inprocess_module": {"path": "reference_controllers/inprocess.py", "sha256": "b" * 64},
        "git": {"revision": "c" * 40, "dirty": True}}))
    assert "a" * 64 in items["program reference_controllers/daemon.py"]
    assert "b" * 64 in items["in-process module reference_controllers/inprocess.py"]
    assert "c" * 40 in items["git revision"] and "differ" in items["git revision"]
    unbuilt = dict(code_items({"program": {"path": "{build_dir}/fw", "sha256": None,
                                           "note": "not built yet"}}))
    assert "not built yet" in unbuilt["program {build_dir}/fw"]
    assert code_items({}) == []
