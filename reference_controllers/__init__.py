"""The papers' reference controllers in Python: pure control cores, CAN adapters, daemons.

* :mod:`reference_controllers.fertilizer`: [F]'s piecewise incremental PID (eq. 11-13), in the
  paper's literal form and in the normalized "physical" form, and the open-loop baseline;
* :mod:`reference_controllers.sowing_depth`: [D]'s fuzzy self-tuning PID (eq. 10, Table 2);
* :mod:`reference_controllers.daemon`: either one as a long-running process on a CAN bus;
* :mod:`reference_controllers.vectors`: the shared test vectors the C firmware replays.

The contract every build implements is ``docs/reference-controllers.md``.
"""
