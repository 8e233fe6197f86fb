"""The main job end to end: both boards and the world in lockstep fly the default mission.

MEMS models to PWM pulses: register-level sensors, drivers, EKF, controllers, the px4io link
at 1.5 Mbit/s, the IO's mixer and timers, ESCs, JSBSim. Run once per seed and checked against
the mission, the world's truth and the FMU's own log.

The second seed's mission carries two more arrangements at once, each checked as if alone: the
motors on four DroneCAN ESCs (issue 22) and the attitude law on the companion computer with the
FMU's own as fallback (issue 24, the paper's arrangement): three boards and the world in
lockstep (FMU, IO, companion on TELEM2 at 921600 baud); the companion runs ``mc_att_control``
unchanged on what the uORB bridge brings it, its rate setpoints come back as
``companion_rates_setpoint`` and the FMU's ``mc_att_companion`` (``MC_ATT_IMPL`` 2) flies them
while fresh and safe. On the way home the TELEM2 cable is pulled (``bus.wire_cut`` on both
conductors): the FMU's law takes over when the latest companion message is MC_CMP_TIMEOUT
(20 ms) old, on the next attitude update (4 ms), and the vehicle flies home and lands.

Measured with seed 1 alone (``hil run --companion-att --seed 1``, 2026-11-27): track error
2.06 m, landing 0.85 m, altitude error 0.66 m, attitude error rms 0.55 deg (the FMU alone:
2.05, 0.85, 0.65, 0.54); cable cut at 46.0 s, the FMU's law 16.3 ms later.
"""

from __future__ import annotations

import filecmp
import re

import numpy as np
import pytest
import pyulog

import hil.flight
from hil.accuracy import TruthSample, estimator_accuracy
from hil.faults import Injector
from firmware.version import os_version_word, version_word
from tests.helpers import fly_in, same_log_start, shared_across_workers

pytestmark = pytest.mark.slow


S = 1_000_000_000
#: the cable cut: on the way home (the default flight reaches waypoint 4 at ~42 s and lands at
#: ~68 s), while still above this height
CUT_AFTER_S = 46.0
CUT_ABOVE_M = 8.0
AFTER_S = 2.0               # the window after the cut whose attitude error is checked
TIMEOUT_MS = 20             # MC_CMP_TIMEOUT's default
PERIOD_MS = 4               # the attitude loop's period


def _fly(tmp_path_factory, seed: int, name: str, **config) -> dict:
    return fly_in(tmp_path_factory, name, seed=seed, keep_truth=True, **config)


class CableCut:
    """An on_quantum hook: pulls the TELEM2 cable once the flight is late enough and high
    enough, after asking the FMU's mc_att_companion how it stood."""

    def __init__(self, orch, dev) -> None:
        self.world = dev["world"].world
        self.injector = Injector(orch, dev).install()
        self.t_cut_s: float | None = None
        self.status_before = ""

    def __call__(self, orch) -> None:
        if self.t_cut_s is not None or orch.t_ns < CUT_AFTER_S * S \
                or self.world.truth().agl_m < CUT_ABOVE_M:
            return
        self.status_before = orch.call("fmu", "shell", "mc_att_companion status")[1]
        self.injector.start("bus.wire_cut", "fmu.telem2")        # FMU -> companion
        self.injector.start("bus.wire_cut", "companion.telem2")  # companion -> FMU
        self.t_cut_s = orch.t_ns / S


def _fly_seed2(tmp_path_factory) -> dict:
    """Seed 2 on CAN ESCs with the attitude law on the companion, the cable cut on the way
    home: the summary, with the cut's time and mc_att_companion's status before it."""
    cuts: list[CableCut] = []
    build = hil.flight.build_system

    def build_with_cut(scfg):
        orch, dev = build(scfg)
        cut = CableCut(orch, dev)
        orch.on_quantum.append(cut)
        cuts.append(cut)
        return orch, dev

    mp = pytest.MonkeyPatch()
    mp.setattr(hil.flight, "build_system", build_with_cut)
    try:
        summary = _fly(tmp_path_factory, 2, "seed2", can_escs=True, companion_att=True)
    finally:
        mp.undo()
    assert len(cuts) == 1
    summary["cut"] = {"t_s": cuts[0].t_cut_s, "status_before": cuts[0].status_before}
    return summary


@pytest.fixture(scope="module")
def flight(tmp_path_factory, worker_id):
    """The seed-1 flight, flown once per test session (tests.helpers.shared_across_workers)."""
    return shared_across_workers(tmp_path_factory, worker_id, "seed1_flight",
                                 lambda: _fly(tmp_path_factory, 1, "seed1"))


@pytest.fixture(scope="module")
def seed2(tmp_path_factory, worker_id):
    """The seed-2 flight (CAN ESCs, the attitude law on the companion, the cable cut)."""
    return shared_across_workers(tmp_path_factory, worker_id, "seed2_flight",
                                 lambda: _fly_seed2(tmp_path_factory))


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


def test_another_seed_flies_on_can_escs_as_accurately(flight, seed2):
    """The second whole mission: seed 2, and the motors on four DroneCAN ESCs (UAVCAN_ENABLE 3,
    hil run --can-escs) instead of the IO's PWM. It must fly the mission with the bounds of the
    seed-1 PWM flight, with the motors driven by CAN: RawCommands received by every ESC node,
    their esc.Status heard, the ESC nodes' outputs running the motors in the climb while the
    IO's outputs, unplugged from the motors, hold their disarmed pulse (no mixer on the IO)."""
    other = seed2
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


def _attitude_error(log: pyulog.ULog) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t_s, error_deg, tilt_error_deg): each logged attitude against the latest logged
    setpoint before it: the whole rotation, and the angle between the body z axes."""
    att = log.get_dataset("vehicle_attitude").data
    sp = log.get_dataset("vehicle_attitude_setpoint").data
    q = np.column_stack([att[f"q[{i}]"] for i in range(4)])
    qd = np.column_stack([sp[f"q_d[{i}]"] for i in range(4)])
    idx = np.searchsorted(sp["timestamp"], att["timestamp"], side="right") - 1
    ok = idx >= 0
    q, qd = q[ok], qd[idx[ok]]
    dot = np.abs(np.sum(q * qd, axis=1)).clip(0.0, 1.0)

    def z_axis(a: np.ndarray) -> np.ndarray:
        w, x, y, z = a.T
        return np.column_stack([2 * (x * z + w * y), 2 * (y * z - w * x),
                                w * w - x * x - y * y + z * z])

    cos_tilt = np.sum(z_axis(q) * z_axis(qd), axis=1).clip(-1.0, 1.0)
    return (att["timestamp"][ok] / 1e6, np.degrees(2.0 * np.arccos(dot)),
            np.degrees(np.arccos(cos_tilt)))


def test_companion_flies_the_mission_and_the_fmu_takes_over_when_the_cable_is_pulled(seed2):
    """The attitude law on the companion flew seed 2's mission to the default flight's checks
    (above, with the CAN ESCs'), no fallback while the cable was in; the FMU's law took over
    MC_CMP_TIMEOUT after the companion's last message once the cable was pulled, without a kick,
    and flew home."""
    summary = seed2
    t_cut_s, before = summary["cut"]["t_s"], summary["cut"]["status_before"]
    names = [p["name"] for p in summary["phases"]]
    t_wp4 = next(p["t_s"] for p in summary["phases"] if p["name"] == "waypoint 4 reached")
    print(f"\ncompanion attitude law: track error max {summary['max_track_error_m']:.2f} m, "
          f"landing {summary['landed_distance_m']:.2f} m, altitude error max "
          f"{summary['max_alt_error_m']:.2f} m, attitude error rms "
          f"{summary['attitude_error_rms_deg']:.2f} deg (FMU only, seed 2 on PWM: 2.20 m, "
          f"0.80 m); cable cut at {t_cut_s} s (waypoint 4 at "
          f"{t_wp4} s)")
    # the default flight's accuracy checks (tests/system/test_flight.py)
    assert summary["waypoints_reached"] == [1, 2, 3, 4]
    assert summary["max_alt_error_m"] < 1.0
    assert summary["landed_distance_m"] < 1.5
    assert names[-1] == "landed and disarmed"

    # the companion flew until the cut: its rate setpoints forwarded, no fallback
    assert t_cut_s is not None and t_cut_s > t_wp4
    print(before)
    assert "source: companion" in before and "fallbacks: 0" in before
    forwarded = int(re.search(r"outputs: (\d+) forwarded", before)[1])
    t_air = t_cut_s - next(p["t_s"] for p in summary["phases"] if p["name"] == "armed")
    assert forwarded > 150 * (t_air - 10.0)    # ~200/s from take-off (the 250 Hz attitude
    #                                            thinned by the 4 ms interval limit)

    log = pyulog.ULog(summary["log"], ["vehicle_attitude", "vehicle_attitude_setpoint"])
    msgs = [(m.timestamp / 1e6, m.message) for m in log.logged_messages
            if m.message.startswith("[mc_att_companion]")]
    print("\n".join(f"{t:.3f} {m}" for t, m in msgs))
    warns = [(t, m) for t, m in msgs if "FMU law flies" in m]
    assert len(warns) == 1, msgs
    t_fb, text = warns[0]
    took_ms = (t_fb - t_cut_s) * 1000.0
    age_ms = float(re.search(r"stale: no companion rate setpoint for ([\d.]+) ms", text)[1])
    max_age_ms = float(re.search(r"max age ([\d.]+) ms", before)[1])
    print(f"FMU law took over {took_ms:.1f} ms after the cut: {text}")
    # the FMU's clock: fallback on the first attitude update after the latest message is
    # MC_CMP_TIMEOUT old; the cut came at most max_age after that message (bytes on the wire
    # at the cut still arrive, ~0.5 ms a frame at 921600 baud)
    assert TIMEOUT_MS < age_ms <= TIMEOUT_MS + PERIOD_MS + 0.5
    assert TIMEOUT_MS - max_age_ms < took_ms <= TIMEOUT_MS + PERIOD_MS + 1.0

    # no kick at the hand-over: the tilt error (the heading's setpoint steps at the corners,
    # so the whole-attitude error is no baseline) against the return leg's before the cut;
    # and the whole-attitude error small
    t_err, err, tilt = _attitude_error(log)
    before_sel = (t_err >= t_cut_s - 3.0) & (t_err < t_cut_s)
    after_sel = (t_err >= t_cut_s) & (t_err < t_cut_s + AFTER_S)
    assert before_sel.sum() > 50 and after_sel.sum() > 50
    tilt_before, tilt_after = float(tilt[before_sel].max()), float(tilt[after_sel].max())
    err_after = float(err[after_sel].max())
    print(f"tilt error max {tilt_before:.2f} deg in the 3 s before the cut, {tilt_after:.2f} "
          f"deg in the {AFTER_S:.0f} s after; attitude error max after {err_after:.2f} deg")
    assert tilt_after <= tilt_before + 1.0
    assert err_after < 3.0
