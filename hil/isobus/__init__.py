"""The tractor side of an ISOBUS implement bench (ISO 11783).

The rig plays the tractor's control functions (tractor ECU, Task Controller) on the same CAN
bus as the implement under test. :mod:`hil.isobus.port` is the seam between the network layer
(NAME and address claim, ISO 11783-5; TP and ETP, ISO 11783-3) and the applications above it
(the Task Controller server, ISO 11783-10): applications send and receive whole parameter
groups through an :class:`~hil.isobus.port.IsobusPort` and never see a transport frame.
"""
