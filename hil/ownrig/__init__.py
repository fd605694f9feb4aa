"""A rig of your own: a plant FMU, its CAN devices from your DBC, judged by standard suites.

A rig file (TOML, :mod:`hil.ownrig.config`) names a co-simulation FMU (FMI 2.0 or 3.0, run by
fmpy), the devices it plays as nodes of the user's DBC (each signal fed from an FMU output
through a sensor model, each command written into an FMU input with an actuator's timeout
behaviour) and the controlled quantities the standard suites (``test_suites/own_rig``) judge.
:func:`hil.ownrig.rig.rig_class` turns the file into a :class:`hil.rig.Rig` subclass that runs
under the one loop like the built-in rigs; its frames go through the same binding layer
(:mod:`hil.contract`) as the built-in rigs' DBC bindings.
"""
