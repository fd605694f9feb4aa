"""The pieces of a qualification session that the pytest plugin (:mod:`hil.pytest_plugin`)
puts together, one idea per module: :mod:`hil.qualification.console` prints it and
:mod:`hil.qualification.verdict` decides its verdict."""
