"""agrihil's plants as Functional Mock-up Units: ``hil fmu export fertilizer``.

The fertilizer rig's plant (drive, meters, transport: the C core of its native engine,
``plant_emulators/fertilizer/native/plant_core.c``) behind the Reference-FMUs skeleton, as an
FMI 2.0 and an FMI 3.0 co-simulation FMU for linux64 (:mod:`.build`); its variables with units
and causality, rig.toml's parameters, the run's draws and a seed as parameters
(:mod:`.variables`).
"""
