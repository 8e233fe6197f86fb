"""rc_update: calibration, mapping, switches, signal-lost detection (reference io-and-rc 9)."""

from __future__ import annotations

import pytest

from firmware.modules.rc_update import mode_slot, scale_channel, switch_position
from tests.flight.test_commander import Rig

MAPPED = {"RC_MAP_ROLL": 1, "RC_MAP_PITCH": 2, "RC_MAP_THROTTLE": 3, "RC_MAP_YAW": 4,
          "RC_MAP_FLTMODE": 5, "RC_MAP_RETURN_SW": 6, "RC_MAP_KILL_SW": 7, "RC_CHAN_CNT": 8,
          "RC3_TRIM": 1000.0, "RC4_REV": -1}
CENTRE = [1500, 1500, 1000, 1500, 1000, 1000, 1000, 1500]


def test_scaling_with_dead_zone_and_reversal() -> None:
    assert scale_channel(1500, 1000, 1500, 2000, 1, 10) == 0.0
    assert scale_channel(1509, 1000, 1500, 2000, 1, 10) == 0.0
    assert scale_channel(2000, 1000, 1500, 2000, 1, 10) == 1.0
    assert scale_channel(2100, 1000, 1500, 2000, 1, 10) == 1.0       # clamped
    assert scale_channel(1000, 1000, 1500, 2000, 1, 10) == -1.0
    assert scale_channel(1755, 1000, 1500, 2000, 1, 10) == pytest.approx(245 / 490)
    assert scale_channel(1755, 1000, 1500, 2000, -1, 10) == pytest.approx(-245 / 490)
    assert scale_channel(1200, 1000, 1000, 2000, 1, 0) == pytest.approx(0.2)  # trim = min


def test_switch_positions_and_mode_slots() -> None:
    assert switch_position(1.0, 0.75) == 1 and switch_position(0.4, 0.75) == 3
    assert switch_position(-1.0, -0.25) == 1 and switch_position(1.0, -0.25) == 3
    # six equal bands over -1.05..1.05
    assert [mode_slot(v) for v in (-1.0, -0.6, -0.2, 0.2, 0.6, 1.0)] == [1, 2, 3, 4, 5, 6]
    assert mode_slot(-2.0) == 1 and mode_slot(2.0) == 6


class RcRig(Rig):
    def __init__(self, **params: float) -> None:
        super().__init__(modules=("rc_update",), params={**MAPPED, **params}, inputs={})
        self.rc_pub = self.orb.advertise("input_rc")

    def send(self, values: list[int], run_s: float = 0.2, **flags: object) -> None:
        """Publish input_rc every 20 ms for ``run_s``."""
        msg = self.orb.new("input_rc", channel_count=len(values), rssi=80, input_source=4)
        msg.values[: len(values)] = values
        for k, v in flags.items():
            setattr(msg, k, v)
        t_end = self.kernel.now_ns + int(run_s * 1e9)
        while self.kernel.now_ns < t_end:
            msg.timestamp = msg.timestamp_last_signal = self.platform.time_us()
            self.rc_pub.publish(msg)
            self.run(0.02)


def test_channels_sticks_and_switches() -> None:
    rig = RcRig()
    rig.send([1750, 1250, 1500, 1745, 1900, 2000, 1000, 1500])
    ch = rig.last("rc_channels")
    assert not ch.signal_lost and ch.channel_count == 8
    assert ch.function[0] == 2 and ch.function[1] == 0       # throttle on channel 3
    man = rig.last("manual_control_setpoint")
    assert man.valid and man.data_source == man.SOURCE_RC
    assert man.roll == pytest.approx(240 / 490) and man.pitch == pytest.approx(-240 / 490)
    assert man.throttle == pytest.approx(0.0)               # trim=min recentred: mid stick
    assert man.yaw == pytest.approx(-235 / 490)              # reversed channel
    sw = rig.last("manual_control_switches")
    assert sw.mode_slot == 6 and sw.return_switch == sw.SWITCH_POS_ON
    assert sw.kill_switch == sw.SWITCH_POS_OFF and sw.arm_switch == sw.SWITCH_POS_NONE
    rig.send([1500, 1500, 1000, 1500, 1000, 1000, 1000, 1500])
    man = rig.last("manual_control_setpoint")
    assert man.throttle == pytest.approx(-1.0) and man.roll == 0.0
    assert rig.last("manual_control_switches").mode_slot == 1


def test_no_manual_control_before_calibration() -> None:
    rig = RcRig(RC_CHAN_CNT=0)
    rig.send(CENTRE)
    assert rig.last("rc_channels") is not None
    assert rig.last("manual_control_setpoint") is None


@pytest.mark.parametrize("flags, values, params", [
    ({"rc_lost": True}, CENTRE, {}),
    ({"rc_failsafe": True}, CENTRE, {}),
    ({}, CENTRE[:3], {}),                                             # < 4 channels
    ({}, [1500, 1500, 900, 1500, 1000, 1000, 1000, 1500], {"RC_FAILS_THR": 950}),
])
def test_signal_lost_conditions(flags: dict, values: list[int], params: dict) -> None:
    rig = RcRig(**params)
    rig.send(CENTRE)
    n0 = rig.orb.node("manual_control_setpoint").publish_count
    rig.send(values, **flags)
    assert rig.last("rc_channels").signal_lost
    assert rig.orb.node("manual_control_setpoint").publish_count == n0
    assert "RC signal lost" in rig.dmesg()


def test_stale_input_and_regain_hysteresis() -> None:
    rig = RcRig()
    rig.send(CENTRE)
    rig.run(0.7)                                                      # the IO stopped
    assert rig.last("rc_channels").signal_lost
    n0 = rig.orb.node("manual_control_setpoint").publish_count
    rig.send(CENTRE, run_s=0.06)
    assert rig.last("rc_channels").signal_lost                        # not believed yet
    rig.send(CENTRE, run_s=0.1)
    assert not rig.last("rc_channels").signal_lost
    assert rig.orb.node("manual_control_setpoint").publish_count > n0
