"""The report says what the GNSS serial line delivered (#20.5), from the run record."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from hil.dut import InProcessDut
from hil.rig import RunOptions, Scenario, run_scenario
from plant_emulators.sowing_depth.controllers import PiDepthController
from plant_emulators.sowing_depth.gnss_serial import LINE_QUEUE_BYTES
from plant_emulators.sowing_depth.rig import SowingDepthRig

from .conftest import FIELD_RUN, STEP_RUN, Page


def _with_epochs(qual: Path, run: str, counts: dict[str, Any]) -> None:
    path = qual / run / "record.json"
    record = json.loads(path.read_text())
    record["truth"] = {**(record.get("truth") or {}), "gnss_epochs": counts}
    path.write_text(json.dumps(record))


def _runs_rows(qual: Path) -> dict[str, str]:
    from hil.report import write_html

    page = Page(write_html(qual).read_text(encoding="utf-8"))
    return {cells[0]: " ".join(cells) for _, cells in page.tables["runs"]}


def test_runs_table_counts_epochs_and_flags_losses(make_qual_dir: Callable[..., Path]) -> None:
    qual = make_qual_dir()
    _with_epochs(qual, STEP_RUN, {"written": 71, "overrun": 2, "dropped": 7, "late": 0,
                                  "unread_bytes": 4095, "first_loss_s": 2.1,
                                  "written_after_loss": 50})
    _with_epochs(qual, FIELD_RUN, {"written": 22, "overrun": 1, "dropped": 48, "late": 1,
                                   "unread_bytes": 4095, "first_loss_s": 2.2,
                                   "written_after_loss": 0})
    rows = _runs_rows(qual)
    step = rows[STEP_RUN]
    assert "GNSS epochs: 71 written, 2 overrun, 7 dropped" in step and "EPOCHS LOST" in step
    field = rows[FIELD_RUN]
    assert "22 written, 1 overrun, 48 dropped, 1 late" in field
    assert "the DUT did not read the port after 2.2 s" in field and "PORT NOT READ" in field
    assert "EPOCHS LOST" not in field


@pytest.mark.parametrize(("after_loss", "not_read"), [(3740, True), (4096, True),
                                                      (4097, False), (9350, False)])
def test_a_port_nobody_reads_is_told_by_the_bytes_after_the_loss(
        make_qual_dir: Callable[..., Path], after_loss: int, not_read: bool) -> None:
    """A port nobody reads still takes up to a line-discipline queue (4,096 bytes) after its
    first loss (the kernel's own buffering, late on a loaded host): epochs got through, yet
    the DUT did not read; more than that, it did."""
    qual = make_qual_dir()
    _with_epochs(qual, FIELD_RUN, {"written": 42, "overrun": 1, "dropped": 38, "late": 0,
                                   "unread_bytes": 4095, "first_loss_s": 2.2,
                                   "written_after_loss": after_loss // 187,
                                   "bytes_after_loss": after_loss,
                                   "line_queue_bytes": LINE_QUEUE_BYTES})
    field = _runs_rows(qual)[FIELD_RUN]
    assert ("PORT NOT READ" in field) is not_read and ("EPOCHS LOST" in field) is not not_read


def test_no_loss_no_flag(make_qual_dir: Callable[..., Path]) -> None:
    qual = make_qual_dir()
    _with_epochs(qual, STEP_RUN, {"written": 80, "overrun": 0, "dropped": 0, "late": 0,
                                  "unread_bytes": 0, "first_loss_s": None,
                                  "written_after_loss": 0})
    step = _runs_rows(qual)[STEP_RUN]
    assert "GNSS epochs: 80 written" in step
    assert "LOST" not in step and "NOT READ" not in step


@pytest.mark.parametrize("duration", [4.0])
def test_sowing_run_records_its_gnss_epochs(tmp_path: Path, duration: float) -> None:
    scenario = Scenario(name="short", description="", rig="sowing_depth", duration_s=duration,
                        initial={"target_depth_mm": 30.0, "ground_speed_mps": 1.1111})
    result = run_scenario(SowingDepthRig, scenario, InProcessDut(PiDepthController()),
                          RunOptions(out_dir=tmp_path, bus="inline", clock="lockstep"))
    counts = result.record["truth"]["gnss_epochs"]
    assert counts["line_queue_bytes"] == LINE_QUEUE_BYTES   # the bound the report judges by
    # 10 Hz for 4 s, epochs at 0.0 … 4.0 s; the built-in PI does not read the GNSS port
    assert counts["written"] + counts["overrun"] + counts["dropped"] + counts["late"] == 41
    assert counts["written"] > 0
    assert counts["dropped"] == 0 or counts["bytes_after_loss"] <= LINE_QUEUE_BYTES
