"""IO firmware behaviour through its wires: status, arming, mixing to PWM, safety button, RC,
corrupt packets, PWM rates, DIRECT_PWM, arming sync after an IO reset."""

from __future__ import annotations

from ioproc.board import BOOT_DELAY_NS
from ioproc.firmware.safety import SAFETY_FIRST_US, SAFETY_PERIOD_US
from ioproc.protocol import (
    LAYOUT,
    Alarms,
    Arming,
    PageNo,
    RawRcFlags,
    ReplyCode,
    Setup,
    StatusFlags,
    encode_read,
    encode_write,
    reg_to_signed,
)
from ioproc.rc.sbus import sbus_raw_to_us
from tests.ioproc.test_io_board import MS, QUAD_X, SbusTx, arm_quad, rig

F = StatusFlags
R = 0.707107  # quad_x roll/pitch factor


def pulses_us(io) -> list[float]:
    return [high / 1000 for high, _ in io.ctl_pwm()]


def quad_pwm(roll: float, thrust: float) -> list[int]:
    """E14 quad_x + pwm_limit ON (min 1000, max 2000) for roll/thrust only, no saturation."""
    out = []
    for r in (-R, R, R, -R):
        m = roll * r + thrust
        o = -1.0 + m * 2.0
        out.append(int(o * 1000 / 2.0 + 1500))
    return out


def test_boot_status_and_alarms() -> None:
    io, fmu = rig()
    io.kernel.run(io.kernel.now_ns + 300 * MS)
    flags, alarms = fmu.read(PageNo.STATUS, 2, 2)
    assert flags == F.FAILSAFE  # no FMU data, no mixer, no RC
    assert alarms == Alarms.FMU_LOST | Alarms.RC_LOST
    assert fmu.write(PageNo.STATUS, 3, [Alarms.RC_LOST]).ok
    assert fmu.alarms() == Alarms.FMU_LOST  # re-latched on every pass while lost
    status = fmu.read(PageNo.STATUS, 0, 9)
    assert status[6] == io.adc.counts_for(5.0 / 3) * 9900 // 4096  # VSERVO mV, 5 V rail
    io.ctl_set_servo_rail_v(4.5)
    assert abs(fmu.read(PageNo.STATUS, 6)[0] - 4500) < 5


def test_controls_make_fmu_ok_and_mixer_upload_sets_failsafe() -> None:
    io, fmu = rig()
    fmu.upload_mixer(QUAD_X)
    assert fmu.flags() & F.MIXER_OK
    # mixer-derived failsafe: zero inputs -> motors at idle (-1) -> 900 µs; the rest 0
    assert fmu.read(PageNo.FAILSAFE_PWM, 0, 8) == [900] * 4 + [0] * 4
    fmu.set_controls()
    fmu.stream()
    fmu.advance(10 * MS)
    assert fmu.flags() & (F.FMU_OK | F.FMU_INITIALIZED) == F.FMU_OK | F.FMU_INITIALIZED
    assert io.ctl_status()["source"] == "fmu"


def test_armed_quad_outputs_follow_controls() -> None:
    io, fmu = rig()
    arm_quad(io, fmu)
    fmu.set_controls(roll=0.1, thrust=0.5)
    fmu.stream()
    fmu.advance(100 * MS)  # pwm_limit INIT: disarmed values (0 = no pulse) for 500 ms
    assert fmu.flags() & F.OUTPUTS_ARMED
    assert pulses_us(io)[:4] == [0, 0, 0, 0]
    fmu.advance(3500 * MS)  # INIT 500 ms + RAMP 2.5 s
    assert io.ctl_status()["pwm_limit"] == "ON"
    expect = quad_pwm(0.1, 0.5)
    assert fmu.read(PageNo.SERVOS, 0, 8) == expect + [0] * 4
    assert pulses_us(io) == [v - 1 for v in expect] + [0] * 4  # E14 CCR = value - 1
    actuators = [reg_to_signed(v) for v in fmu.read(PageNo.ACTUATORS, 0, 4)]
    assert abs(actuators[0] / 10000 - (-1 + 2 * (0.5 - 0.1 * R))) < 2e-4


def test_safety_on_keeps_outputs_disarmed() -> None:
    io, fmu = rig()
    arm_quad(io, fmu, press_safety=True)
    fmu.set_controls(thrust=0.5)
    fmu.stream()
    fmu.advance(1000 * MS)
    assert not fmu.flags() & (F.SAFETY_OFF | F.OUTPUTS_ARMED)
    assert io.ctl_status()["should_arm"] is False
    assert pulses_us(io) == [0] * 8
    assert io.firmware.safety.pattern == 0x5500  # FMU armed, safety on: four flashes


def _sample_times(start_ns: int, count: int) -> list[int]:
    first = BOOT_DELAY_NS + SAFETY_FIRST_US * 1000
    k0 = max(0, -(-(start_ns - first) // (SAFETY_PERIOD_US * 1000)))
    return [first + (k0 + i) * SAFETY_PERIOD_US * 1000 for i in range(count)]


def test_safety_button_toggles_after_eleven_samples() -> None:
    io, fmu = rig()
    arm_quad(io, fmu, press_safety=True)
    k = io.kernel
    t_press = k.now_ns + 5 * MS
    io.deliver([("safety_button", t_press, 1)])
    samples = _sample_times(t_press, 11)
    k.run(samples[10] - 1)
    assert not io.ctl_status()["flags"] & F.SAFETY_OFF
    k.run(samples[10])
    assert io.ctl_status()["flags"] & F.SAFETY_OFF  # the 11th pressed sample
    # holding on does not toggle back; release and hold again turns safety on
    k.run(samples[10] + 2000 * MS)
    assert io.ctl_status()["flags"] & F.SAFETY_OFF
    t_release = k.now_ns + 5 * MS
    # (a release shorter than the 100 ms sampling may never be seen; hold it 150 ms)
    io.deliver([("safety_button", t_release, 0), ("safety_button", t_release + 150 * MS, 1)])
    k.run(t_release + 1300 * MS)
    assert not io.ctl_status()["flags"] & F.SAFETY_OFF


def test_safety_button_needs_io_arm_ok() -> None:
    io, _fmu = rig()
    io.deliver([("safety_button", io.kernel.now_ns, 1)])
    io.kernel.run(io.kernel.now_ns + 2000 * MS)
    assert not io.ctl_status()["flags"] & F.SAFETY_OFF
    assert io.ctl_status()["safety_counter"] == 0


def test_sbus_input_fills_rc_pages() -> None:
    io, fmu = rig()
    fmu.configure_rc()
    rc = SbusTx(io)
    rc.raw[:4] = [1700, 300, 992, 1500]
    rc.start()
    io.kernel.run(io.kernel.now_ns + 100 * MS)
    flags = fmu.flags()
    assert flags & (F.RC_OK | F.RC_SBUS) == F.RC_OK | F.RC_SBUS
    raw = fmu.read(PageNo.RAW_RC_INPUT, 0, 24)
    assert raw[0] == 18 and raw[2] == 255  # count incl. digital 17/18; E14 S.BUS RSSI
    assert raw[6:10] == [sbus_raw_to_us(v) for v in rc.raw[:4]]
    assert raw[1] & RawRcFlags.RC_OK and raw[1] & RawRcFlags.MAPPING_OK
    valid, *controls = fmu.read(PageNo.RC_INPUT, 0, 10)
    assert valid == 0x1F
    us = raw[6:10]
    assert reg_to_signed(controls[0]) == int(10000.0 * (us[0] - 1510) / (2000 - 1510))
    # pitch (control 1) is inverted by the IO
    assert reg_to_signed(controls[1]) == -int(10000.0 * (us[1] - 1490) / (1490 - 1000))
    assert reg_to_signed(controls[2]) == 0  # 1494 µs: inside the 10 µs dead zone


def test_corrupt_requests_and_line_errors() -> None:
    io, fmu = rig()
    bad_crc = bytearray(encode_read(PageNo.CONFIG, 0, 1))
    bad_crc[1] ^= 0x55
    assert fmu.exchange(bytes(bad_crc)) == bytes.fromhex("40bf ffff")
    reply = fmu.exchange(LAYOUT.pack(0x80, 0, 0, (0,)))
    assert reply == LAYOUT.pack(ReplyCode.CORRUPT, 0xFF, 0xFE, ())
    assert fmu.exchange(bytes.fromhex("0129 0000")) == b""  # truncated read: no reply
    # an unknown page: ERROR, no retry
    assert fmu.transact(encode_read(56, 0, 1)).code is ReplyCode.ERROR
    # a line break (framing error) is answered by a break, the packet discarded
    breaks = io.uarts["USART2"].breaks_sent
    fmu.uart.send_break()
    io.kernel.run(io.kernel.now_ns + MS)
    assert io.uarts["USART2"].breaks_sent == breaks + 1
    assert fmu.read(PageNo.CONFIG, 0, 1) == [4]


def test_pwm_rate_change_takes_effect() -> None:
    io, fmu = rig()
    arm_quad(io, fmu)
    fmu.set_controls(thrust=0.5)
    fmu.stream()
    fmu.advance(100 * MS)
    assert [p for _, p in io.ctl_pwm()] == [20_001_000] * 8
    # quirk: ALTRATE alone stores 400 but programs the timers with the stored rates
    fmu.write(PageNo.SETUP, Setup.PWM_ALTRATE, [400])
    fmu.write(PageNo.SETUP, Setup.PWM_RATES, [0x0F])  # groups TIM2 (1-2) and TIM4 (3-4)
    fmu.advance(30 * MS)
    periods = [p for _, p in io.ctl_pwm()]
    assert periods == [2_501_000] * 4 + [20_001_000] * 4  # ARR = 1e6 / 400 = 2500
    # a mask that splits a timer group is refused with PWM_ERROR
    fmu.write(PageNo.SETUP, Setup.PWM_RATES, [0x10])
    assert fmu.alarms() & Alarms.PWM_ERROR
    assert fmu.read(PageNo.SETUP, Setup.PWM_RATES)[0] == 0x0F
    assert fmu.read(PageNo.PWM_INFO, 0, 3) == [0x03, 0xF0, 0x0C]


def test_direct_pwm_bypasses_mixer() -> None:
    io, fmu = rig()
    fmu.configure_rc()
    fmu.write(PageNo.SETUP, Setup.FORCE_SAFETY_OFF, [22027])
    for _ in range(5):
        fmu.write(PageNo.DIRECT_PWM, 0, [1100, 1200, 1300, 1400, 0xFFFF, 1600, 1700, 1800])
        fmu.advance(20 * MS)
    st = io.ctl_status()
    assert st["source"] == "none" and st["flags"] & F.RAW_PWM and st["outputs_armed"]
    assert pulses_us(io) == [1099, 1199, 1299, 1399, 0, 1599, 1699, 1799]


def test_lockdown_stops_timers() -> None:
    io, fmu = rig()
    arm_quad(io, fmu)
    fmu.set_controls(thrust=0.5)
    fmu.stream()
    fmu.advance(50 * MS)
    assert fmu.flags() & F.OUTPUTS_ARMED
    fmu.write(PageNo.SETUP, Setup.ARMING, [Arming.IO_ARM_OK | Arming.FMU_ARMED | Arming.LOCKDOWN])
    fmu.advance(5 * MS)
    assert not fmu.flags() & F.OUTPUTS_ARMED


def test_arm_sync_restores_safety_after_io_reset() -> None:
    io, fmu = rig()
    arm_quad(io, fmu)
    fmu.set_controls(thrust=0.5)
    fmu.stream()
    fmu.advance(50 * MS)
    flags = fmu.flags()
    fmu.write(PageNo.STATUS, 2, [flags | F.ARM_SYNC])
    assert fmu.flags() & F.ARM_SYNC
    fmu.write(PageNo.STATUS, 2, [0])  # ignored while ARM_SYNC is set
    assert fmu.flags() & F.SAFETY_OFF
    fmu.stream(None)
    io.ctl_reset()  # in flight
    io.kernel.run(io.kernel.now_ns + BOOT_DELAY_NS + MS)
    flags = fmu.flags()
    assert not flags & (F.SAFETY_OFF | F.ARM_SYNC)
    # E14 FMU rule: previous copy had SAFETY_OFF, new lacks SAFETY_OFF and ARM_SYNC -> restore
    fmu.write(PageNo.STATUS, 2, [flags | F.SAFETY_OFF | F.ARM_SYNC])
    assert fmu.flags() & (F.SAFETY_OFF | F.ARM_SYNC) == F.SAFETY_OFF | F.ARM_SYNC
    arming = fmu.read(PageNo.SETUP, Setup.ARMING)[0]
    assert arming == 0  # the rebooted IO forgot the arming word; the FMU re-sends it


def test_unknown_request_code_0xc0_is_corrupt() -> None:
    _io, fmu = rig()
    reply = fmu.exchange(LAYOUT.pack(0xC0, 50, 0, ()))
    assert reply == LAYOUT.pack(ReplyCode.CORRUPT, 0xFF, 0xFE, ())
    assert fmu.exchange(encode_write(0, 0, [1]))[0] == ReplyCode.ERROR


def test_ppm_input_through_the_capture_pin() -> None:
    from ioproc.rc import ppm_edges

    io, fmu = rig()
    k = io.kernel
    channels = [1100, 1200, 1300, 1400, 1500, 1600, 1700, 1800]
    t0 = k.now_ns // 1000 + 1000
    records = []
    for frame in range(12):
        for t_us, level in ppm_edges(channels, t0_us=t0 + frame * 22_500):
            records.append(("ppm_in", t_us * 1000, level))
    io.deliver(records)
    k.run((t0 + 12 * 22_500) * 1000)
    assert fmu.flags() & (F.RC_OK | F.RC_PPM) == F.RC_OK | F.RC_PPM
    raw = fmu.read(PageNo.RAW_RC_INPUT, 0, 14)
    assert raw[0] == 8 and raw[3] == 22_500  # frame length in RAW_RC DATA
    assert raw[6:14] == channels


def test_dsm_input_on_usart1() -> None:
    from board.uart import Uart, UartConfig, connect
    io, fmu = rig()
    sat = Uart(io.kernel, "sat", UartConfig(115_200))
    connect(sat, io.uarts["USART1"])
    frame = bytes.fromhex("00 B2 01 56 0C 00 14 00 1C 00 21 56 2E AA 34 00")  # §10.3
    for n in range(40):  # the decoder learns the resolution from ~30 frames first
        io.kernel.call_at(io.kernel.now_ns + n * 11 * MS, sat.write, frame)
    io.kernel.run(io.kernel.now_ns + 40 * 11 * MS)
    flags = fmu.flags()
    assert flags & (F.RC_OK | F.RC_DSM) == F.RC_OK | F.RC_DSM
    raw = fmu.read(PageNo.RAW_RC_INPUT, 0, 13)
    assert raw[0] == 7 and raw[1] & RawRcFlags.RC_DSM11
