"""The standard suites of a rig of your own (a rig file: plant FMU and DBC devices).

They judge every controlled quantity the rig file declares, with no suite code of the rig's
own: step response (response time, overshoot, steady-state error on the truth and as sensed),
tracking over the set-point profile, and robustness (the sensing device silent or frozen, the
controller's frames cut and back, the controller power-cycled). Limits come from the rig file
or the DUT profile; the scenarios are :mod:`hil.ownrig.scenarios`'.
"""
