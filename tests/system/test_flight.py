"""The main job end to end: both boards and the world in lockstep fly the default mission.

MEMS models to PWM pulses: register-level sensors, drivers, EKF, controllers, the px4io link
at 1.5 Mbit/s, the IO's mixer and timers, ESCs, JSBSim. Run once per seed and checked against
the mission, the world's truth and the FMU's own log.
"""

from __future__ import annotations

import filecmp
import re

import numpy as np
import pytest
import pyulog

from hil.accuracy import TruthSample, estimator_accuracy
from firmware.version import os_version_word, version_word
from tests.helpers import fly_in, same_log_start, shared_across_workers

pytestmark = pytest.mark.slow


def _fly(tmp_path_factory, seed: int, name: str, can_escs: bool = False) -> dict:
    return fly_in(tmp_path_factory, name, seed=seed, keep_truth=True, can_escs=can_escs)


@pytest.fixture(scope="module")
def flight(tmp_path_factory, worker_id):
    """The seed-1 flight, flown once per test session (tests.helpers.shared_across_workers)."""
    return shared_across_workers(tmp_path_factory, worker_id, "seed1_flight",
                                 lambda: _fly(tmp_path_factory, 1, "seed1"))


def _phase(summary: dict, prefix: str) -> float:
    return next(p["t_s"] for p in summary["phases"] if p["name"].startswith(prefix))


def test_default_mission_is_flown(flight):
    names = [p["name"] for p in flight["phases"]]
    assert "armed" in names
    assert flight["waypoints_reached"] == [1, 2, 3, 4]  # within NAV_ACC_RAD = 2 m
    assert flight["max_alt_error_m"] < 1.0               # the hover and legs at 10 m
    assert flight["landed_distance_m"] < 1.5
    assert names[-1] == "landed and disarmed"
    assert _phase(flight, "takeoff") < _phase(flight, "waypoint 1") < \
        _phase(flight, "waypoint 4") < _phase(flight, "landed")


def test_estimator_tracks_truth(flight):
    truth = [TruthSample(*row[:4], tuple(row[4:7])) for row in flight["truth"]]
    acc = estimator_accuracy(flight["log"], truth, _phase(flight, "armed"),
                             _phase(flight, "landed"))
    assert acc.attitude_rms_deg < 2.0
    assert acc.tilt_max_deg < 5.0
    assert acc.position_rms_m < 2.0
    assert acc.position_max_m < 5.0
    print(f"estimator vs truth: {acc}")  # measured figures for the closing note


def test_no_estimator_failure_and_outputs_in_range(flight):
    log = pyulog.ULog(flight["log"], ["estimator_status", "actuator_outputs"])
    st = log.get_dataset("estimator_status").data
    assert not np.any(st["filter_fault_flags"])
    out = log.get_dataset("actuator_outputs").data
    for ch in range(4):
        values = out[f"output[{ch}]"]
        assert values.min() >= 900 and values.max() <= 2000, ch


def test_log_has_flight_review_info_keys_and_cpuload(flight):
    """The build's info keys Flight Review reads (as pyulog's ulog_info decodes them), and
    load_mon's cpuload at 2 Hz with the modelled load."""
    log = pyulog.ULog(flight["log"], ["cpuload"])
    info = log.msg_info_dict
    assert re.fullmatch(r"[0-9a-f]{40}", info["ver_sw"])
    assert info["ver_sw_release"] == version_word("fmu-hil 0.1.0")
    assert info["sys_name"] == "PX4" and info["ver_hw"] == "PX4_FMU_V2"
    assert info["sys_os_name"] == "NuttX" and info["sys_os_ver"] == "7.10.0"
    assert info["sys_os_ver_release"] == os_version_word()
    assert info["sys_toolchain"] == "CPython" and re.fullmatch(r"3\.\d+",
                                                                info["sys_toolchain_ver"])
    assert info["sys_mcu"].startswith("STM32F42") and re.fullmatch(r"[0-9A-F]{24}",
                                                                     info["sys_uuid"])
    cpu = log.get_dataset("cpuload").data
    dt = np.diff(cpu["timestamp"])
    assert len(cpu["timestamp"]) > 10 and np.all(dt == 500_000)
    assert np.all((cpu["load"] > 0.05) & (cpu["load"] < 1.0))
    assert np.all(np.isnan(cpu["ram_usage"]))


def test_same_seed_gives_a_byte_identical_log(flight, tmp_path_factory):
    """Seed 1 flown again through the takeoff and the first corners of the square writes, byte
    for byte, the start of the seed-1 flight's log (tests.helpers.same_log_start)."""
    again = fly_in(tmp_path_factory, "seed1again", seed=1, stop_after_s=40.0)
    assert again["waypoints_reached"]
    assert same_log_start(flight["log"], again["log"])


def test_another_seed_flies_on_can_escs_as_accurately(flight, tmp_path_factory):
    """The second whole mission: seed 2, and the motors on four DroneCAN ESCs (UAVCAN_ENABLE 3,
    hil run --can-escs) instead of the IO's PWM. It must fly the mission with the bounds of the
    seed-1 PWM flight, with the motors driven by CAN: RawCommands received by every ESC node,
    their esc.Status heard, the ESC nodes' outputs running the motors in the climb while the
    IO's outputs, unplugged from the motors, hold their disarmed pulse (no mixer on the IO)."""
    other = _fly(tmp_path_factory, 2, "seed2", can_escs=True)
    assert not filecmp.cmp(flight["log"], other["log"], shallow=False)
    assert other["waypoints_reached"] == [1, 2, 3, 4]
    assert other["max_alt_error_m"] < 1.0
    assert other["landed_distance_m"] < 1.5
    assert other["attitude_error_rms_deg"] < 2.0 and other["tilt_error_max_deg"] < 5.0
    assert other["position_error_rms_m"] < 2.0 and other["position_error_max_m"] < 5.0
    # as accurate as the PWM flight along the square (0.5 m of slack for the other seed)
    assert other["max_track_error_m"] < flight["max_track_error_m"] + 0.5
    airborne_s = _phase(other, "landed") - _phase(other, "armed")
    nodes = other["can1"]["nodes"]
    assert sorted(nodes) == [11, 12, 13, 14]
    for nid, n in nodes.items():
        # RawCommand at up to 200 Hz while armed, esc.Status at 10 Hz, none lost
        assert n["commands_rx"] > 150 * airborne_s and n["status_tx"] > 9 * airborne_s, nid
        assert n["rx_errors"] == dict.fromkeys(n["rx_errors"], 0) and not n["silent"], nid
    assert other["can1"]["error_frames"] == 0 and other["can1"]["state"] == "error_active"
    climb = other["outputs_at_takeoff"]
    assert all(1_230_000 <= high_ns <= 1_950_000 and period_ns == 2_500_000
               for high_ns, period_ns in climb["can_esc"])        # the motors run on CAN
    assert all(high_ns <= 900_000 for high_ns, _ in climb["io_pwm"])  # the IO's disarmed pulse
    assert not climb["io_should_arm"]
    status = other["uavcan_status"]
    assert "ESC output: mixer /etc/mixers/quad_x.main.mix" in status
    for i in range(4):
        assert re.search(rf"esc {i}: node {11 + i}, .* errors 0, status \d{{3,}}, ", status)
    log = pyulog.ULog(other["log"], ["esc_status"])
    esc = log.get_dataset("esc_status").data
    assert np.all(esc["esc_online_flags"] == 0b1111) and np.all(esc["esc_count"] == 4)
    assert esc["esc[0].esc_rpm"].max() > 3000   # what the ESC reports in flight
