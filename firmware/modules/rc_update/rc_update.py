"""rc_update: raw RC pulses (``input_rc``) to calibrated channels, sticks and switches.

Runs on every ``input_rc`` publication (the px4io driver's poll rate) plus a 10 Hz watchdog that
notices when the input stops altogether. Conventions (PX4 after 2022):

* ``rc_channels.channels`` are -1..1 after RCn_MIN/TRIM/MAX/DZ and reversal;
* ``manual_control_setpoint``: roll, pitch, yaw and **throttle all -1..1** (throttle -1 = stick
  fully down, 0 = centre). A throttle channel calibrated with TRIM = MIN (an old QGC habit) is
  recentred so it still spans -1..1. pitch is the calibrated pitch channel as is: positive =
  stick forward (nose down), so a transmitter whose forward stick lowers the pulse needs
  RCn_REV = -1 on that channel. An unmapped stick reads 0, an unmapped throttle -1 (idle).
* ``manual_control_setpoint`` and ``manual_control_switches`` are published only while the
  signal is good; the commander detects RC loss from their absence (COM_RC_LOSS_T).

The sticks published are those of the selected manual-control source (PX4's ManualControl
module, here in rc_update as in PX4 before it was split out): RC, or a MAVLink joystick
(MANUAL_CONTROL, which the mavlink links publish on ``manual_control_input`` instances), chosen
by ``COM_RC_IN_MODE`` (:mod:`firmware.modules.rc_update.selector`). The switches are RC's only.

Signal lost (reference io-and-rc 9.3): the receiver/IO says lost or failsafe, fewer than 4
channels, the failsafe channel beyond RC_FAILS_THR, or no ``input_rc`` for 0.5 s. A regained
signal must stay good 100 ms before it is believed.
"""

from __future__ import annotations

from typing import Any, Final

from firmware.modules.rc_update.params import MAX_CHANNELS, PARAMS, SWITCH_MAPS
from firmware.modules.rc_update.selector import ManualControlSelector
from firmware.platform.module import WorkItemModule

__all__ = ["RcUpdateModule", "mode_slot", "scale_channel", "switch_position"]

SWITCH_NONE: Final = 0
SWITCH_ON: Final = 1
SWITCH_MIDDLE: Final = 2
SWITCH_OFF: Final = 3
STALE_US: Final = 500_000        # no input_rc for this long: signal lost
REGAIN_US: Final = 100_000       # a regained signal must stay good this long
WATCHDOG_US: Final = 100_000
MODE_SLOTS: Final = 6
MAVLINK_INPUTS: Final = 4        # manual_control_input instances watched (one per link)
_STICK_MOVING: Final = 0.05

# rc_channels.function indexes (firmware/msg/rc_channels.msg)
F_THROTTLE: Final = 0
F_ROLL: Final = 1
F_PITCH: Final = 2
F_YAW: Final = 3
F_MODE: Final = 4
F_RETURN: Final = 5
F_LOITER: Final = 7
F_OFFBOARD: Final = 8
F_FLAPS: Final = 10
F_AUX1: Final = 11
F_KILL: Final = 20
F_GEAR: Final = 22
F_ARM: Final = 24
_FUNCTION_PARAMS: Final[tuple[tuple[int, str], ...]] = (
    (F_THROTTLE, "RC_MAP_THROTTLE"), (F_ROLL, "RC_MAP_ROLL"), (F_PITCH, "RC_MAP_PITCH"),
    (F_YAW, "RC_MAP_YAW"), (F_MODE, "RC_MAP_FLTMODE"), (F_RETURN, "RC_MAP_RETURN_SW"),
    (F_LOITER, "RC_MAP_LOITER_SW"), (F_OFFBOARD, "RC_MAP_OFFB_SW"), (F_FLAPS, "RC_MAP_FLAPS"),
    (F_KILL, "RC_MAP_KILL_SW"), (F_GEAR, "RC_MAP_GEAR_SW"), (F_ARM, "RC_MAP_ARM_SW"),
) + tuple((F_AUX1 + i, f"RC_MAP_AUX{i + 1}") for i in range(6))
_SWITCH_FUNCTION: Final = {"return_switch": F_RETURN, "loiter_switch": F_LOITER,
                    "offboard_switch": F_OFFBOARD, "kill_switch": F_KILL, "arm_switch": F_ARM,
                    "gear_switch": F_GEAR}


def scale_channel(raw: float, mn: float, trim: float, mx: float, rev: int, dz: float) -> float:
    """PX4's piecewise scaling with a dead zone around TRIM (reference io-and-rc 9.4)."""
    if raw < mn:
        raw = mn
    elif raw > mx:
        raw = mx
    if raw > trim + dz:
        span = mx - trim - dz
        c = (raw - trim - dz) / span if span > 0 else 0.0
    elif raw < trim - dz:
        span = trim - mn - dz
        c = (raw - trim + dz) / span if span > 0 else 0.0
    else:
        c = 0.0
    return -c if rev < 0 else c


def switch_position(value: float, threshold: float) -> int:
    """Two-position switch from a -1..1 channel: ON beyond ``threshold`` of 0..1 travel."""
    v = 0.5 * value + 0.5
    if threshold < 0:
        return SWITCH_ON if v < -threshold else SWITCH_OFF
    return SWITCH_ON if v > threshold else SWITCH_OFF


def mode_slot(value: float) -> int:
    """Flight mode slot 1..6: six equal bands over -1.05..1.05 (0.05 margins beyond the ends)."""
    slot = int((value + 1.05) / 2.1 * MODE_SLOTS) + 1
    return 1 if slot < 1 else min(slot, MODE_SLOTS)


class RcUpdateModule(WorkItemModule):
    NAME = "rc_update"
    DESCRIPTION = "RC calibration and mapping: input_rc -> rc_channels, manual control"
    WQ = "wq:hp_default"
    CPU_COST_NS = 60_000
    PARAMS = PARAMS

    def _start(self) -> None:
        orb = self.platform.orb
        self._pub_ch = self.advertise("rc_channels")
        self._pub_man = self.advertise("manual_control_setpoint")
        self._pub_sw = self.advertise("manual_control_switches")
        self._ch = orb.new("rc_channels")
        self._man = orb.new("manual_control_setpoint")
        self._sw = orb.new("manual_control_switches")
        self._sub_param = self.subscribe("parameter_update")
        assert self.work_item is not None
        self._sub_rc = self.subscribe_callback(self.work_item, "input_rc")
        self._sub_inputs = [self.subscribe_callback(self.work_item, "manual_control_input", i)
                            for i in range(MAVLINK_INPUTS)]
        self.selector = ManualControlSelector()
        self._out = orb.new("manual_control_setpoint")
        self.work_item.schedule_on_interval(WATCHDOG_US)
        self._last_input_us = 0
        self._lost = True
        self._good_since_us: int | None = None
        self._prev_source: tuple[int, int] | None = None
        self._last_sw: tuple[int, ...] | None = None
        self._last_sw_pub_us = 0
        self._prev_sticks = (0.0, 0.0, 0.0, 0.0)
        self._loss_count = 0
        self._load_params()

    # -- parameters -------------------------------------------------------------------------

    def _load_params(self) -> None:
        p = self.param
        self._cal: list[tuple[float, float, float, int, float]] = []
        for n in range(1, MAX_CHANNELS + 1):
            self._cal.append((float(p(f"RC{n}_MIN")), float(p(f"RC{n}_TRIM")),
                              float(p(f"RC{n}_MAX")), int(p(f"RC{n}_REV")),
                              float(p(f"RC{n}_DZ"))))
        function = [-1] * 28
        for f, name in _FUNCTION_PARAMS:
            ch = int(p(name))
            function[f] = ch - 1 if 1 <= ch <= MAX_CHANNELS else -1
        self._function = function
        thr = function[F_THROTTLE]
        if thr >= 0:  # recentre a throttle calibrated with TRIM at the bottom of its travel
            mn, trim, mx, rev, dz = self._cal[thr]
            if (rev >= 0 and trim == mn) or (rev < 0 and trim == mx):
                self._cal[thr] = (mn, (mn + mx) / 2, mx, rev, dz)
        fs = int(p("RC_MAP_FAILSAFE"))
        self._fails_ch = fs - 1 if 1 <= fs <= MAX_CHANNELS else thr
        self._fails_thr = int(p("RC_FAILS_THR"))
        self._chan_cnt = int(p("RC_CHAN_CNT"))
        self._sw_params = [(name, function[_SWITCH_FUNCTION[name]], float(p(th)))
                           for name, (_, th) in SWITCH_MAPS.items()]
        self._sticks_mapped = any(function[f] >= 0 for f in (F_THROTTLE, F_ROLL, F_PITCH, F_YAW))
        params = self.system.params
        sel = self.selector
        sel.rc_in_mode = int(params.get("COM_RC_IN_MODE", 3)) if params is not None else 3
        loss_s = float(params.get("COM_RC_LOSS_T", 0.5)) if params is not None else 0.5
        sel.timeout_us = int(loss_s * 1e6)

    # -- the loop ---------------------------------------------------------------------------

    def run(self) -> None:
        if self._sub_param.updated():
            self._sub_param.copy()
            self._load_params()
        now = self.platform.time_us()
        for sub in self._sub_inputs:
            m = sub.update()
            if m is not None:
                self._offer(m, now)
        rc = self._sub_rc.update()
        if rc is None:
            if not self._lost and self._last_input_us and now - self._last_input_us > STALE_US:
                self._good_since_us = None
                self._set_lost(now, True)
                self._ch.timestamp = now
                self._ch.signal_lost = True
                self._pub_ch.publish(self._ch)
            return
        self._last_input_us = now
        self._process(rc, now)

    def _signal_bad(self, rc: Any) -> bool:
        if rc.rc_lost or rc.rc_failsafe or rc.channel_count < 4:
            return True
        thr, ch = self._fails_thr, self._fails_ch
        if thr > 0 and 0 <= ch < rc.channel_count:
            mn, _, mx, _, _ = self._cal[ch]
            raw = rc.values[ch]
            if (thr < mn and raw < thr) or (thr > mx and raw > thr):
                return True
        return False

    def _set_lost(self, now: int, lost: bool) -> None:
        if lost and not self._lost:
            self._loss_count += 1
            self.warn("RC signal lost")
        elif not lost and self._lost and self._loss_count:
            self.info("RC signal regained")
        self._lost = lost

    def _process(self, rc: Any, now: int) -> None:
        bad = self._signal_bad(rc)
        if bad:
            self._good_since_us = None
            self._set_lost(now, True)
        else:
            if self._good_since_us is None:
                self._good_since_us = now
            if self._lost and (now - self._good_since_us >= REGAIN_US or not self._loss_count):
                self._set_lost(now, False)
        n = min(rc.channel_count, MAX_CHANNELS)
        chans = self._ch.channels
        cal, values = self._cal, rc.values
        for i in range(n):
            mn, trim, mx, rev, dz = cal[i]
            chans[i] = scale_channel(values[i], mn, trim, mx, rev, dz)
        for i in range(n, MAX_CHANNELS):
            chans[i] = 0.0
        ch = self._ch
        ch.timestamp = now
        if not bad:
            ch.timestamp_last_valid = rc.timestamp_last_signal or rc.timestamp
        ch.channel_count = n
        ch.function[:] = self._function
        ch.rssi = max(0, min(255, rc.rssi)) if rc.rssi >= 0 else 0
        ch.signal_lost = self._lost
        ch.frame_drop_count = rc.rc_lost_frame_count
        self._pub_ch.publish(ch)

        source = (rc.input_source, rc.channel_count)
        stable = source == self._prev_source
        self._prev_source = source
        if self._lost or not stable or self._chan_cnt <= 0 or not self._sticks_mapped:
            return
        self._publish_manual(rc, now, n)
        self._publish_switches(rc, now, n)

    def _value(self, function: int, n: int, unmapped: float = 0.0) -> float:
        i = self._function[function]
        if 0 <= i < n:
            c = self._ch.channels[i]
            return -1.0 if c < -1.0 else min(c, 1.0)
        return unmapped

    def _publish_manual(self, rc: Any, now: int, n: int) -> None:
        m = self._man
        m.timestamp = now
        m.timestamp_sample = rc.timestamp
        m.valid = True
        m.data_source = m.SOURCE_RC
        v = self._value
        m.roll, m.pitch, m.yaw = v(F_ROLL, n), v(F_PITCH, n), v(F_YAW, n)
        m.throttle = v(F_THROTTLE, n, -1.0)
        m.flaps = v(F_FLAPS, n)
        m.aux1, m.aux2, m.aux3 = v(F_AUX1, n), v(F_AUX1 + 1, n), v(F_AUX1 + 2, n)
        m.aux4, m.aux5, m.aux6 = v(F_AUX1 + 3, n), v(F_AUX1 + 4, n), v(F_AUX1 + 5, n)
        prev = self._prev_sticks
        sticks = (m.roll, m.pitch, m.yaw, m.throttle)
        m.sticks_moving = any(abs(a - b) > _STICK_MOVING for a, b in zip(sticks, prev)) or \
            abs(m.roll) > _STICK_MOVING or abs(m.pitch) > _STICK_MOVING or \
            abs(m.yaw) > _STICK_MOVING
        self._prev_sticks = sticks
        self._offer(m, now)

    def _offer(self, m: Any, now: int) -> None:
        """Publish ``m`` on manual_control_setpoint if the selector chooses its source."""
        if self.selector.offer(m, now):
            out = self._out
            _copy(m, out)
            out.timestamp = now
            self._pub_man.publish(out)

    def _publish_switches(self, rc: Any, now: int, n: int) -> None:
        sw = self._sw
        mode_ch = self._function[F_MODE]
        sw.mode_slot = mode_slot(self._ch.channels[mode_ch]) if 0 <= mode_ch < n else 0
        chans = self._ch.channels
        for name, i, th in self._sw_params:
            setattr(sw, name, switch_position(chans[i], th) if 0 <= i < n else SWITCH_NONE)
        state = (sw.mode_slot, sw.return_switch, sw.loiter_switch, sw.offboard_switch,
                 sw.kill_switch, sw.arm_switch, sw.gear_switch)
        changed = state != self._last_sw
        if changed and self._last_sw is not None:
            sw.switch_changes += 1
        if changed or now - self._last_sw_pub_us >= 1_000_000:
            self._last_sw = state
            self._last_sw_pub_us = now
            sw.timestamp = now
            sw.timestamp_sample = rc.timestamp
            self._pub_sw.publish(sw)

    def status_lines(self) -> list[str]:
        ch = self._ch
        vals = " ".join(f"{c:+.2f}" for c in ch.channels[: ch.channel_count])
        state = "LOST" if self._lost else "ok"
        return [f"signal {state}, {ch.channel_count} channels, losses {self._loss_count}",
                f"channels: {vals}"]


def _copy(src: Any, dst: Any) -> None:
    """Field by field: the subscription's message stays the broker's."""
    for name in type(src).__slots__:
        setattr(dst, name, getattr(src, name))
