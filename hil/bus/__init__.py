"""Buses: one function turns a spec string into a python-can bus.

>>> from hil.bus import parse_spec
>>> parse_spec("socketcand:127.0.0.1:29536/can0")
BusSpec(transport='socketcand', channel='127.0.0.1:29536/can0', options={})
>>> parse_spec("pcan:PCAN_USBBUS1,bitrate=250000").options
{'bitrate': 250000}
"""

from hil.bus.registry import available_transports, open_bus, register_transport
from hil.bus.spec import BusSpec, parse_spec

__all__ = ["BusSpec", "available_transports", "open_bus", "parse_spec", "register_transport"]
