"""``vtol_att_control`` on a board: it mixes the virtual MC and FW controls into groups 0 and
1 by the state machine's shares, takes DO_VTOL_TRANSITION with one ack, and reports its state."""

import pytest

from tests.helpers import booted_fmu, publish

MS = 1_000_000


@pytest.fixture(scope="module")
def board():
    b = booted_fmu({"SYS_AUTOSTART": 0, "SDLOG_MODE": -1,
                    "VT_F_TRANS_DUR": 2.0, "VT_TRANS_MIN_TM": 0.5,
                    "VT_PSHER_RMP_DT": 1.0})
    assert b.ctl_shell("vtol_att_control start")[0] == 0
    return b


def _run(b, ms, mc, fw):
    """``ms`` of the MC rate loop publishing ``mc`` at 250 Hz while the FW controller
    publishes ``fw``."""
    for _ in range(ms // 4):
        publish(b, "actuator_controls_virtual_fw", control=fw)
        publish(b, "actuator_controls_virtual_mc", control=mc)
        b.kernel.run(b.kernel.now_ns + 4 * MS)


def test_multicopter_mode_passes_the_rotors_and_holds_the_surfaces(board):
    b = board
    mc = [0.1, -0.2, 0.05, 0.6, 0, 0, 0, 0]
    fw = [0.3, 0.4, -0.1, 0.7, 0, 0, 0, 0]
    _run(b, 100, mc, fw)
    ac0 = b.ctl_topic("actuator_controls_0")["control"]
    ac1 = b.ctl_topic("actuator_controls_1")["control"]
    assert ac0[:4] == pytest.approx(mc[:4]) and ac1[:4] == pytest.approx([0, 0, 0, 0])
    assert b.ctl_topic("vtol_vehicle_status")["vehicle_vtol_state"] == 3  # MC


def test_transition_command_is_acked_once_and_ends_in_fixed_wing(board):
    b = board
    mc = [0.1, -0.2, 0.05, 0.6, 0, 0, 0, 0]
    fw = [0.3, 0.4, -0.1, 0.7, 0, 0, 0, 0]
    publish(b, "vehicle_command", command=3000, param1=4.0, source_system=255,
         source_component=190, target_system=1)
    _run(b, 1000, mc, fw)  # no airspeed sensor: the blend runs on VT_F_TRANS_DUR (2 s)
    st = b.ctl_topic("vtol_vehicle_status")
    assert st["vehicle_vtol_state"] == 1 and 0.0 < st["mc_weight"] < 1.0  # half-way
    ack = b.ctl_topic("vehicle_command_ack")
    assert (ack["command"], ack["result"]) == (3000, 0)
    _run(b, 1200, mc, fw)
    assert b.ctl_topic("vtol_vehicle_status")["vehicle_vtol_state"] == 4  # FW
    ac0 = b.ctl_topic("actuator_controls_0")["control"]
    ac1 = b.ctl_topic("actuator_controls_1")["control"]
    assert ac0[:4] == pytest.approx([0, 0, 0, 0]) and ac1[:4] == pytest.approx(fw[:4])
    status, out = b.ctl_shell("vtol_att_control status")
    assert status == 0 and "state FW" in out
