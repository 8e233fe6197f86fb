"""The standard VTOL end to end (SYS_AUTOSTART 13000, the world's QuadPlane): the same FMU and IO
boards, the lift rotors on the IO's MAIN outputs and the surfaces and pusher on the FMU's AUX
outputs, fly its default mission - a vertical takeoff to 30 m, the front transition, the
plane's square of 300 m legs, the back transition and a vertical landing at home - checked as a
PX4 user checks a VTOL flight: both transitions within their limits and no quad-chute, every
waypoint within its acceptance radius, no stall on the wing, the landing within 2 m of home
(the quadrotor's accuracy), disarmed; and against the FMU's own log.

The seed-1 flight (module scope) carries most assertions; seed 2 passes the same mission
checks, and seed 1 flown again through the front transition writes the start of the seed-1
log byte for byte.
"""

from __future__ import annotations

import numpy as np
import pytest
import pyulog

from tests.helpers import fly_in, same_log_start, shared_across_workers

pytestmark = pytest.mark.slow

VTOL = 13000
#: The test flights' lockstep quantum: 1 ms, where ``hil run`` takes 500 us (the flights cost a
#: fifth less; the suite is at its time limit).
QUANTUM_NS = 1_000_000


def _fly(tmp_path_factory, seed: int, name: str, stop_after_s: float | None = None) -> dict:
    return fly_in(tmp_path_factory, name, seed=seed, airframe=VTOL, stop_after_s=stop_after_s,
                  quantum_ns=QUANTUM_NS)


@pytest.fixture(scope="module")
def vtol(tmp_path_factory, worker_id):
    """The VTOL's seed-1 mission, flown once per test session."""
    return shared_across_workers(tmp_path_factory, worker_id, "vtol_seed1",
                                 lambda: _fly(tmp_path_factory, 1, "vtol_seed1"))


def _transition_checks(vtol: dict) -> None:
    names = [p["name"] for p in vtol["phases"]]
    order = [n for n in names if n.startswith("vtol: ")]
    assert order == ["vtol: transition to fixed wing", "vtol: fixed wing",
                     "vtol: transition to multicopter", "vtol: multicopter"], order
    assert vtol["transitions_ok"] and not vtol["quad_chute"]
    assert 0.0 < vtol["front_transition_s"] <= vtol["front_transition_limit_s"]  # timeout
    assert vtol["back_transition_s"] == pytest.approx(vtol["back_transition_limit_s"], abs=0.4)
    # the rotors hold the height while the wing takes over (the world's truth)
    assert vtol["front_transition_height_loss_m"] < 5.0


def _square_and_landing_checks(vtol: dict) -> None:
    assert vtol["waypoints_reached"] == [1, 2, 3, 4]
    log = pyulog.ULog(vtol["log"], ["position_controller_status"])
    radius = max(float(np.nanmax(log.get_dataset("position_controller_status")
                                 .data["acceptance_radius"])),
                 float(log.initial_parameters["NAV_ACC_RAD"]))
    assert max(vtol["waypoint_miss_m"]) <= radius, (vtol["waypoint_miss_m"], radius)
    assert vtol["max_aoa_deg"] < vtol["stall_aoa_deg"]            # never near the stall
    assert vtol["cruise_max_alt_error_m"] < 5.0                    # of the mission's 30 m
    assert vtol["landed_distance_m"] < 2.0                         # the quadrotor's accuracy
    assert vtol["phases"][-1]["name"] == "landed and disarmed"
    assert vtol["attitude_error_rms_deg"] < 2.0 and vtol["position_error_rms_m"] < 3.0


def test_vtol_transitions_within_their_limits_and_without_a_quad_chute(vtol):
    _transition_checks(vtol)


def test_vtol_flies_the_square_on_the_wing_and_lands_at_home(vtol):
    _square_and_landing_checks(vtol)


def test_vtol_another_seed_and_the_same_seed_again(vtol, tmp_path_factory):
    """Seed 2 through the vertical takeoff, the front transition and the first waypoint on the
    wing (the whole mission of seed 2 passes too, measured) makes a clean front transition with
    another log; seed 1 flown again to 45 s writes the start of the seed-1 log byte for
    byte."""
    other = _fly(tmp_path_factory, 2, "vtol_seed2", stop_after_s=60.0)
    names = [p["name"] for p in other["phases"]]
    assert names.index("vtol: transition to fixed wing") < names.index("vtol: fixed wing")
    assert not other["quad_chute"] and other["waypoints_reached"][:1] == [1]
    assert 0.0 < other["front_transition_s"] <= other["front_transition_limit_s"]
    assert other["front_transition_height_loss_m"] < 5.0
    assert other["max_aoa_deg"] < other["stall_aoa_deg"]
    assert not same_log_start(vtol["log"], other["log"], min_bytes=0)
    again = _fly(tmp_path_factory, 1, "vtol_seed1_again", stop_after_s=45.0)
    assert "vtol: fixed wing" in [p["name"] for p in again["phases"]]
    assert same_log_start(vtol["log"], again["log"])


def test_vtol_log_has_both_flight_modes(vtol):
    """The FMU's ULog says standard VTOL (MAV_TYPE 22), both vehicle types in turn, the VTOL
    module's states, the rotors and the surfaces both working, and the pusher run."""
    log = pyulog.ULog(vtol["log"])
    topics = {d.name for d in log.data_list}
    assert {"vtol_vehicle_status", "airspeed", "actuator_controls_1"} <= topics
    vs = log.get_dataset("vehicle_status").data
    assert set(vs["system_type"]) == {22} and set(vs["vehicle_type"]) == {1, 2}
    assert set(vs["is_vtol"]) == {1}
    st = log.get_dataset("vtol_vehicle_status").data
    assert {1, 2, 3, 4} <= set(st["vehicle_vtol_state"])
    assert not np.any(st["fixed_wing_system_failure"])
    ac0 = log.get_dataset("actuator_controls_0").data
    ac1 = log.get_dataset("actuator_controls_1").data
    assert np.ptp(ac0["control[3]"]) > 0.3                          # lift rotors' thrust
    assert np.ptp(ac1["control[1]"]) > 0.1 and np.max(ac1["control[3]"]) > 0.4  # elevator, pusher
