"""What the IO does when things fail: FMU silence, RC loss, receiver failsafe, manual override,
flight termination (E14, io-and-rc.md §3.3-§3.7). Times are asserted exactly where the
firmware's timeouts define them: a timeout expires on the first 1 ms main-loop pass after it."""

from __future__ import annotations

from ioproc.board import BOOT_DELAY_NS, IoV2Board
from ioproc.firmware.controls import RC_INPUT_LOST_US
from ioproc.firmware.mixer_tick import FMU_INPUT_DROP_LIMIT_US
from ioproc.protocol import Alarms, Arming, PageNo, RawRcFlags, Setup, StatusFlags, reg_to_float
from tests.ioproc.test_io_board import MS, FakeFmu, SbusTx, arm_quad, rig

F = StatusFlags
#: roll -> output 1, pitch -> output 2 (a two-surface plane, enough to watch the sticks)
PLANE = ("M: 1\nO: 10000 10000 0 -10000 10000\nS: 0 0 10000 10000 0 -10000 10000\n"
         "M: 1\nO: 10000 10000 0 -10000 10000\nS: 0 1 10000 10000 0 -10000 10000\n")


def first_pass_after(t_us: int, limit_us: int) -> int:
    """ns time of the first main-loop pass (1 ms grid from boot) with now - t > limit."""
    n = ((t_us + limit_us) * 1000 - BOOT_DELAY_NS) // MS + 1
    return BOOT_DELAY_NS + n * MS


def pwm_log(io: IoV2Board, port: str) -> list[tuple[int, int, int]]:
    log: list[tuple[int, int, int]] = []
    spec = next(o for o in io.spec.pwm if o.port == port)
    io.timers[spec.timer].channel(spec.channel).on_pwm(lambda t, h, p: log.append((t, h, p)))
    return log


def test_fmu_silence_gives_failsafe_values() -> None:
    io, fmu = rig()
    arm_quad(io, fmu)
    fmu.set_controls(thrust=0.6)
    fmu.stream(20 * MS)
    fmu.advance(600 * MS)
    fmu.write(PageNo.STATUS, 3, [0xFF])  # clear the boot-time alarms
    assert io.ctl_status()["source"] == "fmu" and io.ctl_pwm()[0][0] > 0
    fmu.stream(None)
    last_us = io.firmware.regs.fmu_data_received_us
    log = pwm_log(io, "pwm1")
    t_lost = first_pass_after(last_us, FMU_INPUT_DROP_LIMIT_US)
    io.kernel.run(t_lost - 1)
    assert io.ctl_status()["flags"] & F.FMU_OK
    io.kernel.run(t_lost)
    st = io.ctl_status()
    assert not st["flags"] & F.FMU_OK and st["alarms"] & Alarms.FMU_LOST
    assert st["flags"] & F.FAILSAFE and st["source"] == "failsafe"
    assert io.firmware.regs.page(PageNo.SERVOS)[:4] == [900] * 4  # mixer-derived failsafe
    io.kernel.run(t_lost + 21 * MS)
    t, high, period = log[-1]
    assert (high, period) == (899_000, 20_001_000)  # E14 CCR = 900 - 1
    assert t_lost <= t <= t_lost + period  # preloaded CCR shows at the next update event
    assert io.ctl_status()["outputs_armed"]  # FMU_ARMED is still the last word written
    # the FMU comes back: FMU_OK with its first CONTROLS write
    fmu.stream(20 * MS)
    fmu.advance(MS)
    assert fmu.flags() & F.FMU_OK and io.ctl_status()["source"] == "fmu"


def test_custom_failsafe_values() -> None:
    io, fmu = rig()
    arm_quad(io, fmu)
    fmu.write(PageNo.FAILSAFE_PWM, 0, [1000, 1100, 1200, 1300, 0, 0, 0, 0])
    assert fmu.read(PageNo.SETUP, Setup.ARMING)[0] & Arming.FAILSAFE_CUSTOM
    io.kernel.run(io.kernel.now_ns + 2 * MS)  # FMU never sent controls: failsafe at once
    # arming loads the CCR preset at init (1000) with UG; the new values follow one period later
    assert [h // 1000 for h, _ in io.ctl_pwm()[:4]] == [1000] * 4
    io.kernel.run(io.kernel.now_ns + 21 * MS)
    assert [h // 1000 for h, _ in io.ctl_pwm()[:4]] == [999, 1099, 1199, 1299]


def _rc_rig(mode_channel: int | None = 5, arming: int = 0) -> tuple[IoV2Board, FakeFmu, SbusTx]:
    io, fmu = rig()
    fmu.configure_rc(8, mode_channel=mode_channel)
    fmu.upload_mixer(PLANE)
    fmu.write(PageNo.SETUP, Setup.ARMING, [Arming.IO_ARM_OK | Arming.FMU_ARMED | arming])
    fmu.write(PageNo.SETUP, Setup.FORCE_SAFETY_OFF, [22027])
    rc = SbusTx(io)
    rc.raw[0] = 1700  # roll stick right
    rc.raw[5] = 1800  # mode switch: not manual
    rc.start()
    fmu.set_controls(roll=-0.25)
    fmu.stream(20 * MS)
    return io, fmu, rc


def _roll_pwm(fmu: FakeFmu, roll: float) -> int:
    return int(roll * 1000 / 2.0 + 1500)


def test_override_switch_gives_rc_to_outputs() -> None:
    io, fmu, rc = _rc_rig(arming=Arming.MANUAL_OVERRIDE_OK)
    fmu.advance(3100 * MS)  # pwm_limit INIT + RAMP
    assert io.ctl_status()["source"] == "fmu"
    assert fmu.read(PageNo.SERVOS, 0, 1)[0] == _roll_pwm(fmu, -0.25)
    rc.raw[5] = 200  # switch to manual: scaled -10000 < -8000
    fmu.advance(40 * MS)
    st = io.ctl_status()
    assert st["flags"] & F.OVERRIDE and st["source"] == "override_fmu_ok"
    rc_roll = reg_to_float(fmu.read(PageNo.RC_INPUT, 1)[0])
    assert rc_roll > 0.8
    assert fmu.read(PageNo.SERVOS, 0, 1)[0] == _roll_pwm(fmu, rc_roll)


def test_override_refused_without_permission() -> None:
    io, fmu, rc = _rc_rig()
    rc.raw[5] = 200
    fmu.advance(100 * MS)
    assert not io.ctl_status()["flags"] & F.OVERRIDE


def test_fmu_loss_with_override_immediate_flies_on_rc() -> None:
    io, fmu, _rc = _rc_rig(arming=Arming.MANUAL_OVERRIDE_OK | Arming.OVERRIDE_IMMEDIATE)
    fmu.advance(3100 * MS)
    fmu.stream(None)
    last_us = io.firmware.regs.fmu_data_received_us
    t_lost = first_pass_after(last_us, FMU_INPUT_DROP_LIMIT_US)
    io.kernel.run(t_lost + 30 * MS)  # FMU_OK drops at t_lost; override on the next RC pass
    st = io.ctl_status()
    assert st["source"] == "override" and st["flags"] & F.OVERRIDE
    rc_roll = reg_to_float(io.firmware.regs.page(PageNo.RC_INPUT)[1])
    assert io.firmware.regs.page(PageNo.SERVOS)[0] == _roll_pwm(fmu, rc_roll)


def test_termination_failsafe_latches_and_refuses_override() -> None:
    arming = (Arming.MANUAL_OVERRIDE_OK | Arming.OVERRIDE_IMMEDIATE
              | Arming.TERMINATION_FAILSAFE)
    io, fmu, _rc = _rc_rig(arming=arming)
    fmu.advance(600 * MS)
    fmu.stream(None)
    io.kernel.run(io.kernel.now_ns + 600 * MS)
    st = io.ctl_status()
    assert st["source"] == "failsafe" and "FORCE_FAILSAFE" in st["arming_names"]
    assert io.firmware.regs.page(PageNo.SERVOS)[:2] == [1500, 1500]  # centred surfaces
    fmu.stream(20 * MS)
    fmu.write(PageNo.SETUP, Setup.ARMING, [Arming.IO_ARM_OK | Arming.FMU_ARMED])
    fmu.advance(50 * MS)
    st = io.ctl_status()
    assert "FORCE_FAILSAFE" in st["arming_names"] and "TERMINATION_FAILSAFE" in st[
        "arming_names"]
    assert st["source"] == "failsafe"


def test_rc_loss_clears_rc_ok_within_200_ms() -> None:
    io, fmu, rc = _rc_rig(arming=Arming.MANUAL_OVERRIDE_OK)
    rc.raw[5] = 200
    fmu.advance(100 * MS)
    fmu.write(PageNo.STATUS, 3, [0xFF])
    assert io.ctl_status()["flags"] & (F.RC_OK | F.OVERRIDE) == F.RC_OK | F.OVERRIDE
    rc.stop()
    fmu.stream(None)
    io.kernel.run(io.kernel.now_ns + 5 * MS)  # the frame on the wire still arrives
    last_us = io.firmware.controls.rc_received_us
    t_lost = first_pass_after(last_us, RC_INPUT_LOST_US)
    io.kernel.run(t_lost - 1)
    assert io.ctl_status()["flags"] & F.RC_OK
    io.kernel.run(t_lost)
    st = io.ctl_status()
    assert not st["flags"] & (F.RC_OK | F.OVERRIDE | F.RC_SBUS)
    assert st["alarms"] & Alarms.RC_LOST
    raw = io.firmware.regs.page(PageNo.RAW_RC_INPUT)
    assert raw[0] == 0 and not raw[1] & RawRcFlags.RC_OK
    assert io.firmware.regs.page(PageNo.RC_INPUT)[0] == 0


def test_receiver_failsafe_flag_cancels_override() -> None:
    io, fmu, rc = _rc_rig(arming=Arming.MANUAL_OVERRIDE_OK)
    rc.raw[5] = 200
    fmu.advance(60 * MS)
    assert io.ctl_status()["flags"] & F.OVERRIDE
    rc.failsafe = True
    fmu.advance(60 * MS)
    raw = fmu.read(PageNo.RAW_RC_INPUT, 0, 3)
    assert raw[1] & RawRcFlags.FAILSAFE and raw[2] == 0  # E14 S.BUS RSSI 0 on failsafe
    st = io.ctl_status()
    assert st["flags"] & F.RC_OK and not st["flags"] & F.OVERRIDE
