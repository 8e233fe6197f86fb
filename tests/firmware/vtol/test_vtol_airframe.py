"""The standard VTOL airframe (SYS_AUTOSTART 13000) boots as PX4's rc.vtol_apps does: the FMU's
own outputs run with the AUX mixer (rc.interface's MIXER_AUX), the multicopter rate controller
publishes virtual controls for vtol_att_control, which alone writes the real groups; and the
host wires the FMU's AUX outputs to the world only for a model that uses them."""

import pytest

from fmu.board import FmuV2Board
from board.wiring import FMU_AUX_WIRES, PIXHAWK1, WORLD, with_fmu_aux

MS = 1_000_000


@pytest.fixture(scope="module")
def board():
    b = FmuV2Board(seed=1, sd_root=None, params={"SYS_AUTOSTART": 13000, "SDLOG_MODE": -1},
                   extra_devices=("ms4525",))
    b.kernel.run(1_500 * MS)
    return b


def test_the_aux_mixer_runs_on_the_fmu(board):
    status, out = board.ctl_shell("fmu status")
    assert status == 0 and "mixer: /etc/mixers/vtol_AETR.aux.mix (4 outputs)" in out, out
    assert "rate [50] Hz" in out                      # PWM_AUX_RATE: servos and the pusher
    assert board.ctl_shell("param get MAV_TYPE")[1].strip() == "22"
    assert board.ctl_shell("param get VT_TYPE")[1].strip() == "2"


def test_only_vtol_att_control_writes_the_real_control_groups(board):
    orb = board.platform.orb
    assert orb.node("actuator_controls_virtual_mc").last is not None
    status, out = board.ctl_shell("mc_rate_control status")
    assert "publishes actuator_controls_virtual_mc" in out
    _, vtol = board.ctl_shell("vtol_att_control status")
    assert "state MC" in vtol
    # every group-0 and group-1 publication is vtol_att_control's (one per virtual MC run)
    n_virtual = orb.node("actuator_controls_virtual_mc").generation
    assert orb.node("actuator_controls_0").generation == pytest.approx(n_virtual, abs=1)
    assert orb.node("actuator_controls_1").generation == pytest.approx(n_virtual, abs=1)
    st = board.ctl_topic("vehicle_status")
    assert st["is_vtol"] and st["vehicle_type"] == 1 and not st["in_transition_mode"]


def test_aux_wires_only_for_the_channels_a_model_uses():
    assert with_fmu_aux(PIXHAWK1, 0) == PIXHAWK1
    quad_plane = with_fmu_aux(PIXHAWK1, 4)
    added = quad_plane[len(PIXHAWK1):]
    assert added == FMU_AUX_WIRES[:4]
    assert [(w.src, w.dst) for w in added] == [(("fmu", f"aux{i}"), (WORLD, f"aux{i}"))
                                              for i in range(1, 5)]


def test_extended_sys_state_reports_the_vtol_state(board):
    """PX4 fills EXTENDED_SYS_STATE.vtol_state from vtol_vehicle_status (a ground station's
    VTOL indicator); MAV_VTOL_STATE uses the same numbers."""
    from firmware.modules.mavlink.streams import _extended_sys_state

    inst = board.system.modules.get("mavlink").instances[0]
    msg = _extended_sys_state(inst)
    assert msg.vtol_state == 3                             # MAV_VTOL_STATE_MC


def test_hil_names_the_vtol_and_its_mission():
    from hil.airframes import resolve
    from hil.missions import mission_for

    frame = resolve("vtol")
    assert (frame.id, frame.vehicle_class, frame.host.world_model) == (13000, "vtol", "quadplane")
    assert resolve("quadplane") == frame and resolve("Generic Standard VTOL") == frame
    mission = mission_for("vtol")
    cmds = [it.cmd for it in mission.plan]
    assert cmds == [22, 3000, 16, 16, 16, 16, 3000, 21]    # takeoff, to FW, square, to MC, land
    assert [it.param1 for it in mission.plan if it.cmd == 3000] == [4.0, 3.0]
    assert mission.plan[mission.first_waypoint_seq].cmd == 16
