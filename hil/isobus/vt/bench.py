"""The VT and one implement on a virtual wire, in virtual time: for tests and the operator.

:class:`VtBench` puts the rig's VT (:func:`~hil.isobus.vt.server.add_vt`) on one
:class:`~hil.isobus.network.IsobusNetwork` and an implement's control function on another,
joined by a :class:`~hil.isobus.wire.VirtualWire`: every frame goes through the real network
layer (address claim, TP, ETP) in virtual time, deterministic from run to run. The implement
runs a :class:`~hil.isobus.vt.client.VtClient` unless ``client=False`` (then the test runs its
own applications on :attr:`VtBench.implement_cf`).
"""

from __future__ import annotations

from collections.abc import Sequence

from hil.isobus.name import IsobusName
from hil.isobus.network import IsobusNetwork
from hil.isobus.vt.client import VtClient
from hil.isobus.vt.server import VirtualTerminalServer, VtOptions, add_vt
from hil.isobus.vt.store import VersionStore
from hil.isobus.wire import VirtualWire

IMPLEMENT_NAME = IsobusName(identity_number=0x2A, manufacturer_code=100, function=128,
                            device_class=5, industry_group=2)
IMPLEMENT_ADDRESS = 0x84


class VtBench:
    """The VT and an implement joined in virtual time (see the module docstring)."""

    def __init__(self, transfers: Sequence[bytes] = (), *, version_label: bytes | None = None,
                 options: VtOptions | None = None, store: VersionStore | None = None,
                 client: bool = True, client_version: int = 4,
                 vt_start_s: float = 0.0) -> None:
        self.rig = IsobusNetwork(name="rig", start_s=vt_start_s)
        self.vt: VirtualTerminalServer = add_vt(self.rig, options, store)
        self.implement = IsobusNetwork(name="implement")
        self.implement_cf = self.implement.add(IMPLEMENT_NAME, IMPLEMENT_ADDRESS, "implement")
        self.client: VtClient | None = None
        if client:
            self.client = VtClient(self.implement_cf, list(transfers), version_label,
                                   client_version)
            self.implement_cf.run(self.client)
        self.wire = VirtualWire([self.rig, self.implement])

    @property
    def now(self) -> float:
        """The run time reached."""
        return self.wire.now

    def run_until(self, end_s: float) -> None:
        """Advance the wire to run time ``end_s``."""
        self.wire.run_until(end_s)

    def run_for(self, seconds: float) -> None:
        """Advance the wire by ``seconds``."""
        self.wire.run_until(self.wire.now + seconds)
