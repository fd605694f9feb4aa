"""A qualification session, one module per idea; the pytest plugin (:mod:`hil.pytest_plugin`)
is a thin layer over it (options, markers, fixtures).

- :mod:`~hil.qualification.session`: :class:`QualificationSession`, which puts the others
  together, from a qualification's first run to its record;
- :mod:`~hil.qualification.runs`: the scenario runs, cached and shared between tests;
- :mod:`~hil.qualification.conformance_runs`: the bus conformance of each run;
- :mod:`~hil.qualification.measurements`: measurements judged by their limits and kept;
- :mod:`~hil.qualification.outcomes`: a test's outcome from its measurements;
- :mod:`~hil.qualification.summary`: how many measurements were judged, how many information;
- :mod:`~hil.qualification.record`: the record (``record.json``) and the HTML report;
- :mod:`~hil.qualification.verdict`: the session's verdict;
- :mod:`~hil.qualification.console`: what the console prints;
- :mod:`~hil.qualification.suites`: the suites and which ones a run selects.

Nothing is imported here: ``import hil.qualification`` runs no module of the package.
"""
