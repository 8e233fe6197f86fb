"""ESCs on CAN (UAVCAN_ENABLE 3): the FMU mixes actuator_controls_0 with the airframe's mixer
(``mixer load /dev/uavcan/esc``) and sends RawCommand; four ESC nodes take their element,
drive their motor output port with the equivalent pulse train, report esc.Status, and stop
when disarmed or when the commands stop."""

from __future__ import annotations

from fmu.board import FmuV2Board

MS = 1_000_000
PERIOD_NS = 2_500_000


def _pulse(raw):
    return (1_000_000 + round(1_000_000 * raw / 8191), PERIOD_NS)


def test_mixed_raw_commands_reach_the_esc_nodes_and_their_motor_outputs(tmp_path):
    b = FmuV2Board(seed=1, fram_path=str(tmp_path / "fram.bin"), sd_root=str(tmp_path),
                   params={"SYS_AUTOSTART": 0, "UAVCAN_ENABLE": 3, "UAVCAN_EC_MIN": 1884},
                   uavcan_nodes=("esc1@11", "esc2@12", "esc3@13", "esc4@14"))
    k = b.kernel
    escs = b.can_nodes
    k.run(1_000 * MS)
    ok, out = b.ctl_shell("mixer load /dev/uavcan/esc /etc/mixers/quad_x.main.mix")
    assert ok == 0, out
    # the test stands in for the commander and the rate controller
    orb = b.platform.orb
    armed_pub, ctl_pub = orb.advertise("actuator_armed"), orb.advertise("actuator_controls_0")
    armed, ctl = orb.new("actuator_armed"), orb.new("actuator_controls_0")

    def fly(controls, ms, arm=True):
        armed.armed = arm
        armed_pub.publish(armed)
        for _ in range(ms * 1000 // 2500):  # the rate controller's 400 Hz
            ctl.control = list(controls) + [0.0] * 4
            ctl_pub.publish(ctl)
            k.run(k.now_ns + 2_500_000)

    fly((0, 0, 0, 0.0), 100, arm=False)
    assert [e.raw for e in escs] == [0] * 4 and all(e.commands_rx > 0 for e in escs)
    assert b.port_levels["can_esc1"] == _pulse(0)  # 0 stops the motor
    fly((0, 0, 0, 0.0), 100)
    assert [e.raw for e in escs] == [1884] * 4  # armed at zero thrust: UAVCAN_EC_MIN
    rx0 = escs[0].commands_rx
    fly((0, 0, 0, 0.5), 100)
    assert [e.raw for e in escs] == [5038] * 4  # 1884 + 0.5 x (8191 - 1884)
    # controls at 400 Hz, RawCommand at PX4's 200 Hz: 20 in 100 ms
    assert 19 <= escs[0].commands_rx - rx0 <= 21
    assert [b.port_levels[f"can_esc{i}"] for i in range(1, 5)] == [_pulse(5038)] * 4
    st = b.ctl_topic("esc_status")  # what the ESCs report, as PX4's esc_status
    assert st["esc_count"] == 4 and st["esc_online_flags"] == st["esc_armed_flags"] == 0b1111
    assert all(e["esc_rpm"] >= 2000 and e["esc_current"] > 0 for e in st["esc"][:4])
    # roll right: the left motors (PX4 quad X: 2 rear left, 3 front left) speed up
    fly((0.2, 0, 0, 0.5), 50)
    r = [e.raw for e in escs]
    assert r[1] == r[2] > 5038 > r[0] == r[3]
    _, out = b.ctl_shell("uavcan status")
    assert "ESC output: mixer /etc/mixers/quad_x.main.mix" in out
    for i, e in enumerate(escs):
        assert f"esc {i}: node {e.node_id}, " in out and e.status_tx >= 3
    # the commands stop (a hung FMU, a cut bus): each ESC stops its motor after 0.5 s
    k.run(k.now_ns + 450 * MS)
    assert not escs[0].timed_out
    k.run(k.now_ns + 200 * MS)
    assert all(e.timed_out for e in escs) and b.port_levels["can_esc1"] == (0, PERIOD_NS)
