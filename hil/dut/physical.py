"""A physical ECU on a real bus: the rig does not start it, it only checks it is there.

Before each run waits for the ECU, :meth:`PhysicalDut.announce` prints every endpoint the
outside device needs (the bus spec to join, the GNSS receiver's serial port, the node id it
must answer as and the frames the rig expects from it) and writes them to
``ecu-endpoints.json`` in the run directory, so a bridge or an operator can connect it. The run
then waits for the ECU's CANopen heartbeat (any NMT state); none within
``launch.ready_timeout_s`` is a setup error naming the bus and the frame id. A physical ECU
cannot be power-cycled by the rig: :meth:`PhysicalDut.restart` refuses, and qualification skips
the scenarios that need it (see :data:`RESTART_SKIP_REASON`).
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from hil.bus import open_bus
from hil.dut.base import DutError, DutRunner
from hil.dut.profile import DutProfile

#: the file in the run directory that lists the endpoints
ENDPOINTS_FILE = "ecu-endpoints.json"
#: why a scenario that power-cycles the DUT does not apply to a physical ECU
RESTART_SKIP_REASON = ("the rig cannot power-cycle a physical ECU (it does not start it): "
                       "scenario {scenario} restarts the DUT")


class PhysicalDutSetupError(DutError):
    """The physical ECU is not there (no heartbeat): a setup problem, not a DUT verdict."""


def endpoints(profile: DutProfile, bus_spec: str, env: dict[str, str] | None,
              bitrate_bps: int | None = None) -> dict[str, Any]:
    """What an outside ECU needs to join a run of the rig, as a JSON-able mapping.

    Parameters
    ----------
    profile
        The physical DUT's profile (its wiring says which node it must answer as).
    bus_spec
        The bus the rig is on (what the ECU, or its bridge, must join).
    env
        The rig's DUT environment (e.g. ``AGRIHIL_GNSS_PORT``: the GNSS receiver's pty).
    bitrate_bps
        The rig's CAN bit rate, when known.
    """
    wiring = profile.wiring
    env = dict(env or {})
    found: dict[str, Any] = {
        "dut": profile.name,
        "rig": profile.dut.rig,
        "bus": bus_spec,
        "node_id": wiring.node_id,
        "heartbeat_id": f"0x{wiring.heartbeat_id:03X}",
        "command_ids": [f"0x{i:X}" for i in wiring.command_ids],
        "control_period_ms": profile.timing.control_period_ms,
        "heartbeat_period_ms": profile.timing.heartbeat_period_ms,
        "database": wiring.database,
        "gnss_port": env.get("AGRIHIL_GNSS_PORT"),
        "environment": env,
        "waits_for": (f"a heartbeat 0x{wiring.heartbeat_id:03X} within "
                      f"{profile.launch.ready_timeout_s:g} s"),
    }
    if bitrate_bps:
        found["bitrate_bps"] = bitrate_bps
    return found


def write_endpoints(run_dir: Path, found: dict[str, Any]) -> Path:
    """Write ``found`` to ``run_dir/ecu-endpoints.json`` atomically (temporary + rename)."""
    run_dir.mkdir(parents=True, exist_ok=True)
    target = run_dir / ENDPOINTS_FILE
    fd, tmp = tempfile.mkstemp(dir=run_dir, prefix=".ecu-endpoints.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as fh:
            json.dump(found, fh, indent=2)
            fh.write("\n")
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return target


class PhysicalDut(DutRunner):
    """Waits for the ECU's heartbeat (any NMT state) on start; nothing to stop."""

    def __init__(self, profile: DutProfile) -> None:
        self.profile = profile
        self.name = profile.name
        self.seen_state: int | None = None
        self.endpoints_path: Path | None = None

    def announce(self, run_dir: Path, bus_spec: str, env: dict[str, str] | None = None,
                 bitrate_bps: int | None = None) -> dict[str, Any]:
        """Print the endpoints (stderr, one line each) and write them to the run directory.

        Called by the runner before :meth:`start` waits for the ECU.
        """
        found = endpoints(self.profile, bus_spec, env, bitrate_bps)
        self.endpoints_path = write_endpoints(Path(run_dir), found)
        lines = [f"physical ECU {self.name}: join bus {bus_spec}"
                 + (f" ({bitrate_bps} bit/s)" if bitrate_bps else ""),
                 f"  answer as node {found['node_id']} (0x{found['node_id']:02X}): heartbeat "
                 f"{found['heartbeat_id']}, command frames "
                 f"{', '.join(found['command_ids']) or '(any)'}"]
        if found["gnss_port"]:
            lines.append(f"  GNSS receiver (NMEA 0183): {found['gnss_port']}")
        lines.append(f"  waiting for {found['waits_for']}; endpoints in "
                     f"{self.endpoints_path}")
        for line in lines:
            print(f"hil: {line}", file=sys.stderr, flush=True)
        return found

    def start(self, bus_spec: str, env: dict[str, str] | None = None) -> None:
        """Wait for the ECU's heartbeat (any NMT state), up to its ``launch.ready_timeout_s``.

        Parameters
        ----------
        bus_spec : str
            The bus the ECU is on.
        env : dict of str to str, optional
            Unused: the ECU is not started by the rig.

        Raises
        ------
        PhysicalDutSetupError
            No heartbeat within the timeout (naming the bus, the frame id and the endpoints file).
        """
        heartbeat = self.profile.wiring.heartbeat_id
        timeout = self.profile.launch.ready_timeout_s
        bus = open_bus(bus_spec)
        try:
            deadline = time.monotonic() + timeout
            while time.monotonic() < deadline:
                msg = bus.recv(0.1)
                if msg is not None and msg.arbitration_id == heartbeat and msg.data:
                    self.seen_state = msg.data[0]
                    return
        finally:
            bus.shutdown()
        where = f"; endpoints: {self.endpoints_path}" if self.endpoints_path else ""
        raise PhysicalDutSetupError(
            f"physical DUT {self.name!r}: no heartbeat 0x{heartbeat:03X} on {bus_spec} within "
            f"{timeout:g} s: is it powered, wired to this bus and at its bit rate?{where}")

    def restart(self, bus_spec: str, env: dict[str, str] | None = None) -> dict[str, Any]:
        """Refuse: the rig cannot power-cycle a physical ECU.

        Raises
        ------
        DutError
            Always.
        """
        raise DutError("the rig cannot power-cycle a physical ECU (it does not start it)")

    def check(self) -> None:
        """Nothing to check: the rig does not run the ECU (the bus shows what it does)."""
        return None

    def stop(self, timeout: float = 5.0) -> dict[str, Any]:
        """Nothing to stop; return what the record keeps: the NMT state seen, the endpoints file."""
        found: dict[str, Any] = {"name": self.name, "kind": "physical",
                                 "nmt_state_at_start": self.seen_state}
        if self.endpoints_path is not None:
            # the file's name in the run's directory: the directory moves into --out when
            # the command ends (a staging path would name nothing by then)
            found["endpoints"] = self.endpoints_path.name
        return found

    def identity(self) -> dict[str, Any]:
        """The profile's identity of the DUT (:meth:`DutProfile.identity`)."""
        return self.profile.identity()
