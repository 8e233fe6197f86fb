"""The plugin as a user sees it: registered by its entry point, fixtures available, and a
condition that does not hold within its virtual budget fails the test with a clear message."""

from __future__ import annotations

pytest_plugins = ["pytester"]


def test_plugin_fixtures_and_virtual_time_timeouts(pytester):
    pytester.makepyfile(test_user='''
        import pytest
        from hil.pytest_plugin import HilTimeout

        def test_wait_too_short(hil_vehicle):
            hil_vehicle.wait_for("gps_fix >= 3", within=0.2)

        def test_bad_fault_is_a_clear_error(hil_vehicle):
            from hil.faults import FaultError
            with pytest.raises(FaultError, match="target 'fmu' is not one of"):
                hil_vehicle.fault("sensor.absent", "fmu")
            with pytest.raises(ValueError, match="unknown observable"):
                hil_vehicle.read("warp")
    ''')
    result = pytester.runpytest_subprocess("-q", "-p", "no:cacheprovider")
    result.assert_outcomes(passed=1, failed=1)
    result.stdout.fnmatch_lines(["*HilTimeout*'gps_fix >= 3' did not hold within 0.2 virtual s*"])
