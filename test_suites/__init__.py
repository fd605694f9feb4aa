"""The standard qualification suites (pytest files using the agrihil plugin).

Run them through ``hil qualify PROFILE`` or directly::

    pytest test_suites -c test_suites/pytest.ini --hil-dut PROFILE --hil-report out
"""
