"""Bus conformance of the DUT: its frames checked against its databases, as measurements.

Per run, from the frames the recorder logged (``bus.log``) and the DUT's databases (the rig's
DBC through cantools, the EDS of the rig's CANopen nodes through canopen, the profile's
wiring and timing): undeclared frames, data lengths, cycle times, heartbeat, boot-up, the
DUT's share of the bit rate and, in real time, the SYNC-to-command latency. Every suite run
records them (the pytest plugin calls :func:`run_conformance` after each run). See
``docs/guide/bus-conformance.md``.

Modules: :mod:`.framelog` (the log as numpy columns), :mod:`.rigs` (each rig's databases),
:mod:`.declared` (what the DUT may send), :mod:`.checks` (pure functions of the columns),
:mod:`.measure` (measurements with limits).
"""

from hil.conformance.measure import Conformance, contract_of, run_conformance, write_detail

__all__ = ["Conformance", "contract_of", "run_conformance", "write_detail"]
