"""Functional Mock-up Units as DUTs: loading (fmpy), FMI-LS-BUS CAN, and the importer's bus.

* :mod:`hil.fmi.fmufile`: an FMU on disk, fmpy's validation, its CAN terminals;
* :mod:`hil.fmi.instance`: one running instance (FMI 2.0/3.0 co-simulation, event mode);
* :mod:`hil.fmi.lsbus`: the LS-BUS 1.0 CAN operations, encoded and decoded;
* :mod:`hil.fmi.canbus`: the bus simulation a CAN node FMU sees (confirm, arbitration, errors);
* :mod:`hil.fmi.bus_node`, :mod:`hil.fmi.signal_node`: bus-level and signal-level FMUs as
  controllers (frames in, frames out);
* :mod:`hil.fmi.parameters`: a profile's parameters as the FMU's;
* :mod:`hil.fmi.host`: the FMU host, a process of its own that runs the FMU for the rig.

The DUT profile side is :mod:`hil.dut.fmu`.
"""
