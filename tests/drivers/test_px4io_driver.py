"""px4io driver (E14) against a fake IO over a real UART pair at 1.5 Mbit/s.

The fake answers with the real register pages (ioproc.pages) through handle_request, so what
is asserted here is what the IO would hold: the mixer text, the arming bits, the PWM pages.
"""

from __future__ import annotations

import itertools
import random
import time

import pytest

from firmware.drivers.px4io.link import IO_LOST_CALLS
from ioproc.mixer import filter_mixer_file
from ioproc.protocol import (
    Alarms,
    ArmingA,
    PageNo,
    RawRcFlags,
    Setup,
    StatusFlags,
    encode_write,
)
from tests.drivers.px4io_fake_io import (
    MIXER,
    controls_publisher,
    io_board_rig,
    make_rig,
    mixer_text_from_writes,
)

# -- init ------------------------------------------------------------------------------------

def test_init_reads_config_then_configures_and_uploads_the_mixer():
    rig = make_rig()
    io = rig.io
    first = io.requests[0]
    assert first.data == bytes.fromhex("01 29 00 00 00 00")  # §1.5 worked example
    assert [r.offset for r in io.reads_of(PageNo.CONFIG)][:8] == [0, 1, 5, 4, 8, 3, 6, 2]
    romfs = rig.system.resolve_path(f"/etc/mixers/{MIXER}").read_text()
    assert mixer_text_from_writes(io.writes_to(PageNo.MIXERLOAD)) == \
        filter_mixer_file(romfs) + "\n"
    regs = io.regs
    assert regs.status_flags & StatusFlags.MIXER_OK
    assert regs.status_flags & StatusFlags.ARM_SYNC
    assert regs.status_flags & StatusFlags.INIT_OK  # RC config accepted
    setup = regs.page(PageNo.SETUP)
    assert (setup[Setup.PWM_DEFAULTRATE], setup[Setup.PWM_ALTRATE], setup[Setup.PWM_RATES]) \
        == (50, 400, 0x0F)
    assert regs.page(PageNo.CONTROL_MIN_PWM) == [1000] * 8
    assert regs.page(PageNo.CONTROL_MAX_PWM) == [2000] * 8
    assert regs.page(PageNo.DISARMED_PWM) == [900] * 8
    assert regs.page(PageNo.FAILSAFE_PWM)[:4] == [900] * 4  # mixer-derived, not custom
    rc = regs.page(PageNo.RC_CONFIG)
    assert rc[0:6] == [1000, 1500, 2000, 10, 0, 1]  # channel 1 = roll
    assert rc[2 * 6 + 4] == 3 and rc[8 * 6 + 4] == 255
    assert "IO ready: protocol 4" in rig.dmesg()
    assert rig.driver.state == "running"


def test_wrong_protocol_version_is_refused_with_a_clear_message():
    rig = make_rig(protocol_version=5)
    text = rig.dmesg()
    assert "IO protocol version 5, this driver speaks version 4 (E14)" in text
    assert rig.module is None  # stopped, as a failed `px4io start`
    assert not rig.io.writes_to(PageNo.MIXERLOAD)
    n = len(rig.io.requests)
    rig.run_ms(100)
    assert len(rig.io.requests) == n  # nothing more sent


def test_missing_io_gives_up_after_the_retry_window():
    rig = make_rig(start=False)
    rig.io.silent = True
    assert rig.cmd("start") == 0
    rig.run_ms(600)
    assert rig.module is not None  # still retrying the protocol read
    rig.run_ms(200)
    assert "IO not installed" in rig.dmesg()
    assert rig.module is None


# -- controls --------------------------------------------------------------------------------

def test_one_controls_write_has_the_exact_bytes():
    rig = make_rig()
    rig.publish("actuator_controls_0", control=[0.1, -0.2, 0.3, 0.5, 0, 0, 0, -1.0])
    rig.run_ms(1)
    writes = rig.io.writes_to(PageNo.CONTROLS)
    assert len(writes) == 1
    expected = bytes.fromhex("48 9d 33 00 e8 03 30 f8 b8 0b 88 13 00 00 00 00 00 00 f0 d8")
    assert writes[0].data == expected
    assert expected == encode_write(51, 0, [1000, -2000 & 0xFFFF, 3000, 5000, 0, 0, 0,
                                            -10000 & 0xFFFF])
    assert rig.io.regs.page(PageNo.CONTROLS)[:4] == [1000, 63536, 3000, 5000]


def test_controls_follow_a_400_hz_publisher_and_the_limit():
    rig = make_rig()
    controls_publisher(rig, 400)
    rig.run_ms(500)
    n400 = len(rig.io.writes_to(PageNo.CONTROLS))
    assert 198 <= n400 <= 201
    assert rig.io.regs.status_flags & StatusFlags.FMU_OK
    assert rig.cmd("limit", "100") == 0  # E14: 1000/100 = 10 ms
    start = len(rig.io.writes_to(PageNo.CONTROLS))
    rig.run_ms(500)
    n100 = len(rig.io.writes_to(PageNo.CONTROLS)) - start
    assert 49 <= n100 <= 51


def test_other_groups_are_written_at_their_offset():
    rig = make_rig()
    rig.publish("actuator_controls_2", control=[0.5] * 8)
    rig.publish("actuator_controls_0", control=[0.0] * 8)
    rig.run_ms(25)
    offsets = {w.offset for w in rig.io.writes_to(PageNo.CONTROLS)}
    assert offsets == {0, 16}
    assert rig.io.regs.page(PageNo.CONTROLS)[16:24] == [5000] * 8


# -- status and RC polling -------------------------------------------------------------------

def test_status_and_rc_are_polled_every_20_ms_and_input_rc_is_published():
    rig = make_rig()
    channels = [1500, 1510, 1100, 1520, 1900, 1000, 1200, 1300, 1400, 1600, 1700, 1800]
    rig.io.set_rc(channels, rssi=200)
    controls_publisher(rig, 400)
    t0 = rig.platform.time_us()
    rig.run_ms(300)
    polls = [r.t_us for r in rig.io.reads_of(PageNo.STATUS, 2) if r.t_us > t0]
    gaps = [b - a for a, b in itertools.pairwise(polls)]
    assert len(polls) >= 14
    assert all(19_000 <= g <= 21_000 for g in gaps), gaps
    assert rig.io.reads_of(PageNo.RAW_RC_INPUT, 15)  # 12 channels: a second read
    rc = rig.topic("input_rc")
    assert rc.channel_count == 12
    assert rc.values[:12] == channels and rc.values[12:] == [0] * 6
    assert not rc.rc_lost and not rc.rc_failsafe
    assert rc.input_source == 4  # PX4IO S.BUS
    assert rc.rssi == 200
    assert rc.timestamp_last_signal == rc.timestamp
    out = rig.topic("actuator_outputs")
    assert out.noutputs == 8
    status = rig.topic("px4io_status")
    assert status.status_rc_ok and status.status_rc_sbus and status.status_arm_sync
    assert status.raw_inputs[:12] == channels


def test_rc_failsafe_and_loss_are_reported_in_input_rc():
    rig = make_rig()
    rig.io.set_rc([1500] * 8, flags=RawRcFlags.RC_OK | RawRcFlags.FAILSAFE)
    rig.run_ms(40)
    rc = rig.topic("input_rc")
    assert rc.rc_failsafe and not rc.rc_lost
    last = rc.timestamp_last_signal
    rig.io.set_rc([], flags=0)
    rig.io.regs.alarms |= Alarms.RC_LOST
    rig.run_ms(40)
    rc = rig.topic("input_rc")
    assert rc.rc_lost and rc.channel_count == 0
    assert rc.timestamp_last_signal == last
    assert "IO alarm: RC lost" in rig.dmesg()


def test_fmu_lost_alarm_of_the_io_is_reported_once():
    rig = make_rig()
    rig.io.regs.alarms |= Alarms.FMU_LOST
    rig.run_ms(100)
    assert rig.dmesg().count("IO alarm: FMU lost") == 1
    assert rig.topic("px4io_status").alarm_fmu_lost


# -- link errors -----------------------------------------------------------------------------

def test_a_corrupted_reply_is_retried_and_succeeds():
    rig = make_rig()
    rig.io.corrupt_next = 1
    rig.publish("actuator_controls_0", control=[0.25] * 8)
    rig.run_ms(2)
    writes = rig.io.writes_to(PageNo.CONTROLS)
    assert len(writes) == 2 and writes[0].data == writes[1].data
    assert rig.perf("io_crcerrs") == 1
    assert rig.perf("io_retries") == 1
    assert rig.perf("io_timeouts") == 0
    assert rig.driver.link.consecutive_failures == 0


def test_no_reply_times_out_after_10_ms_three_attempts_counted():
    rig = make_rig()
    rig.io.silent = True
    rig.publish("actuator_controls_0", control=[0.25] * 8)
    rig.run_ms(35)
    writes = rig.io.writes_to(PageNo.CONTROLS)
    assert len(writes) == 3
    assert [b.t_us - a.t_us for a, b in itertools.pairwise(writes)] == [10_000, 10_000]
    assert rig.perf("io_timeouts") == 3
    assert rig.perf("io_retries") == 2
    assert rig.driver.link.consecutive_failures >= 1


def test_a_dropped_request_costs_one_timeout_then_succeeds():
    rig = make_rig()
    rig.io.drop_next = 1
    rig.publish("actuator_controls_0", control=[0.25] * 8)
    rig.run_ms(12)
    assert len(rig.io.writes_to(PageNo.CONTROLS)) == 2
    assert rig.perf("io_timeouts") == 1 and rig.perf("io_retries") == 1
    assert rig.io.regs.page(PageNo.CONTROLS)[0] == 2500


def test_a_late_reply_to_an_earlier_attempt_does_not_confuse_the_next_call():
    rig = make_rig()
    rig.io.delay_next_us = [12_000]  # the reply comes after the 10 ms timeout
    rig.publish("actuator_controls_0", control=[0.25] * 8)
    rig.run_ms(100)
    assert rig.perf("io_timeouts") == 1
    assert rig.driver.state == "running"
    assert rig.driver.link.consecutive_failures == 0


def test_an_error_reply_is_not_retried():
    rig = make_rig()
    rig.io.error_pages.add(PageNo.CONTROLS)
    rig.publish("actuator_controls_0", control=[0.25] * 8)
    rig.run_ms(2)
    assert len(rig.io.writes_to(PageNo.CONTROLS)) == 1
    assert rig.perf("io_errors") == 1
    assert rig.perf("io_retries") == 0
    assert "refused" in rig.driver.link.last_error


def test_a_silent_io_is_reported_lost_then_restored():
    rig = make_rig()
    rig.io.silent = True
    rig.run_ms(IO_LOST_CALLS * 30 + 100)
    assert "IO lost" in rig.dmesg()
    assert rig.driver.link.lost
    rig.io.silent = False
    rig.run_ms(100)
    assert "IO link restored" in rig.dmesg()
    assert not rig.driver.link.lost
    assert rig.topic("px4io_status").link_errors >= IO_LOST_CALLS * 3


def test_garbage_replies_never_crash_the_driver():
    rig = make_rig()
    rng = random.Random(7)
    orig = rig.io._send

    def mangle(reply: bytes) -> None:
        choice = rng.random()
        if choice < 0.3:
            reply = bytes(rng.randrange(256) for _ in range(rng.randrange(0, 70)))
        elif choice < 0.5:
            reply = reply[:rng.randrange(len(reply) + 1)]
        elif choice < 0.6:
            rig.io.uart.send_break()
            return
        orig(reply)

    rig.io._send = mangle
    controls_publisher(rig, 400)
    rig.run_ms(500)
    assert rig.driver.state == "running"
    rig.io._send = orig
    before = len(rig.io.writes_to(PageNo.CONTROLS))
    rig.run_ms(100)
    assert len(rig.io.writes_to(PageNo.CONTROLS)) - before >= 38
    assert rig.perf("io_crcerrs") + rig.perf("io_badidle") + rig.perf("io_uarterrs") > 0


# -- arming, safety, reboot ------------------------------------------------------------------

def test_fmu_arming_sets_the_arming_bits_on_the_io():
    rig = make_rig()
    rig.publish("actuator_armed", armed=True, ready_to_arm=True)
    rig.run_ms(220)
    arming = rig.io.regs.arming
    assert arming & ArmingA.FMU_ARMED and arming & ArmingA.IO_ARM_OK
    assert not arming & (ArmingA.LOCKDOWN | ArmingA.FORCE_FAILSAFE)
    rig.publish("actuator_armed", armed=True, ready_to_arm=True, lockdown=True,
                force_failsafe=True)
    rig.run_ms(220)
    assert rig.io.regs.arming & ArmingA.LOCKDOWN and rig.io.regs.arming & ArmingA.FORCE_FAILSAFE
    rig.publish("actuator_armed", armed=False, ready_to_arm=True)
    rig.run_ms(220)
    arming = rig.io.regs.arming
    assert not arming & (ArmingA.FMU_ARMED | ArmingA.LOCKDOWN | ArmingA.FORCE_FAILSAFE)
    assert arming & ArmingA.ALWAYS_PWM_ENABLE  # the IO's own bit survives the RMW
    assert rig.topic("px4io_status").arming_io_arm_ok


def test_safety_off_and_on_commands():
    rig = make_rig()
    assert rig.cmd("safety_off") == 0
    rig.run_ms(25)
    assert rig.io.regs.status_flags & StatusFlags.SAFETY_OFF
    assert any(w.data == bytes.fromhex("41 12 32 0C 0B 56")
               for w in rig.io.writes_to(PageNo.SETUP))  # §1.5 worked example
    assert rig.cmd("safety_on") == 0
    rig.run_ms(25)
    assert not rig.io.regs.status_flags & StatusFlags.SAFETY_OFF


def test_io_reboot_is_detected_and_the_io_configured_again():
    rig = make_rig()
    uploads = len(rig.io.writes_to(PageNo.MIXERLOAD))
    rig.io.reboot()
    rig.run_ms(50)
    assert "IO reboot detected" in rig.dmesg()
    assert len(rig.io.writes_to(PageNo.MIXERLOAD)) == 2 * uploads
    regs = rig.io.regs
    assert regs.status_flags & StatusFlags.MIXER_OK and regs.status_flags & StatusFlags.ARM_SYNC
    assert regs.page(PageNo.DISARMED_PWM) == [900] * 8
    assert regs.page(PageNo.SETUP)[Setup.PWM_ALTRATE] == 400
    rig.run_ms(30)
    assert rig.topic("px4io_status").io_reboots == 1
    assert "IO in-air restart" not in rig.dmesg()


def test_io_reboot_in_flight_restores_arming_and_safety():
    rig = make_rig()
    controls_publisher(rig, 400)
    rig.publish("actuator_armed", armed=True, ready_to_arm=True)
    rig.cmd("safety_off")
    rig.run_ms(250)
    assert rig.io.regs.status_flags & StatusFlags.SAFETY_OFF
    rig.io.reboot()
    rig.run_ms(60)
    regs = rig.io.regs
    assert "IO in-air restart: safety off restored" in rig.dmesg()
    assert regs.status_flags & StatusFlags.SAFETY_OFF
    assert regs.status_flags & StatusFlags.MIXER_OK  # uploaded before safety went off
    assert regs.arming & ArmingA.FMU_ARMED and regs.arming & ArmingA.IO_ARM_OK


def test_status_command_prints_flags_and_counters():
    rig = make_rig()
    rig.console.clear()
    assert rig.cmd("status") == 0
    text = "".join(rig.console)
    assert "mixer: quad_x.main.mix (MIXER_OK)" in text
    assert "MIXER_OK ARM_SYNC INIT_OK" in text
    assert "px4io: io_txns" in text
    assert rig.cmd("bogus") == 1


# -- cost ------------------------------------------------------------------------------------

def test_host_cost_per_virtual_second(capsys):
    """Printed, not asserted: 400 Hz controls + 50 Hz polling, fake IO included."""
    rig = make_rig()
    controls_publisher(rig, 400)
    rig.io.set_rc([1500] * 8)
    t0 = time.perf_counter()
    rig.run_ms(1000)
    host_s = time.perf_counter() - t0
    n = len(rig.io.requests)
    with capsys.disabled():
        print(f"\npx4io: {host_s * 1000:.1f} ms host per virtual second "
              f"({n} transactions incl. fake IO)")
    assert rig.driver.state == "running"



# -- end to end with the emulated IO board ---------------------------------------------------

def test_end_to_end_with_the_io_board():
    rig, board = io_board_rig()
    assert rig.cmd("start", "-m", MIXER) == 0  # at power-on: the IO is in its bootloader
    rig.run_ms(400)
    assert "IO ready: protocol 4" in rig.dmesg(), rig.dmesg()
    st = board.ctl_status()
    assert {"MIXER_OK", "ARM_SYNC", "INIT_OK"} <= set(st["flag_names"])
    assert board.ctl_registers(PageNo.DISARMED_PWM) == [900] * 8
    controls_publisher(rig, 400, values=(0.0, 0.0, 0.0, 0.5))
    rig.publish("actuator_armed", armed=True, ready_to_arm=True)
    rig.cmd("safety_off")
    rig.run_ms(3500)  # E14 PWM limit: 0.5 s init + 2.5 s ramp
    st = board.ctl_status()
    assert st["outputs_armed"] and "SAFETY_OFF" in st["flag_names"]
    pulses = [high // 1000 for high, _ in board.ctl_pwm()[:4]]
    assert all(1400 <= p <= 1600 for p in pulses), pulses
    out = rig.topic("actuator_outputs").output[:4]
    assert all(1400 <= v <= 1600 for v in out), out
    board.ctl_reset()  # brown-out in flight
    rig.run_ms(600)
    text = rig.dmesg()
    assert "IO reboot detected" in text and "safety off restored" in text, text
    st = board.ctl_status()
    assert {"MIXER_OK", "ARM_SYNC", "SAFETY_OFF"} <= set(st["flag_names"])
    assert "FMU_ARMED" in st["arming_names"]


def test_an_fmu_stall_seen_by_the_io_board_is_reported_each_time():
    rig, board = io_board_rig()
    rig.cmd("start", "-m", MIXER)
    rig.run_ms(300)
    for _ in range(2):
        for _ in range(100):  # 250 ms of controls, then 700 ms of silence
            rig.publish("actuator_controls_0", control=[0.0] * 8)
            rig.run_ms(2.5)
        rig.run_ms(700)
        assert "FMU_LOST" in board.ctl_status()["alarm_names"]
    rig.publish("actuator_controls_0", control=[0.0] * 8)
    rig.run_ms(50)
    text = rig.dmesg()
    assert text.count("IO alarm: FMU lost") == 2, text
    assert text.count("IO: FMU controls arriving again") == 2, text


# -- parameters and restarts -----------------------------------------------------------------

def test_parameter_changes_reach_the_io_within_200_ms():
    rig = make_rig()
    params = rig.system.params
    params.set("PWM_DISARMED", 1000)
    params.set("PWM_MAIN_FAIL2", 1200)
    params.set("PWM_RATE", 200)
    rig.run_ms(220)
    regs = rig.io.regs
    assert regs.page(PageNo.DISARMED_PWM) == [1000] * 8
    assert regs.page(PageNo.FAILSAFE_PWM)[1] == 1200
    assert regs.arming & ArmingA.FAILSAFE_CUSTOM
    assert regs.page(PageNo.SETUP)[Setup.PWM_ALTRATE] == 200
    assert rig.topic("px4io_status").pwm_disarmed == [1000] * 8


def test_io_safety_circuit_breaker_forces_safety_off_after_the_mixer():
    rig = make_rig(start=False)
    rig.system.params.set("CBRK_IO_SAFETY", 22027)
    rig.cmd("start", "-m", MIXER)
    rig.run_ms(60)
    flags = rig.io.regs.status_flags
    assert flags & StatusFlags.SAFETY_OFF and flags & StatusFlags.MIXER_OK


def test_fmu_restart_in_air_keeps_the_io_armed_and_asks_to_arm():
    rig = make_rig(start=False)
    regs = rig.io.regs
    regs.arming = ArmingA.FMU_ARMED | ArmingA.IO_ARM_OK | ArmingA.INAIR_RESTART_OK
    regs.status_flags = (StatusFlags.SAFETY_OFF | StatusFlags.ARM_SYNC | StatusFlags.INIT_OK
                         | StatusFlags.MIXER_OK | StatusFlags.FMU_INITIALIZED)
    sub = rig.platform.orb.node("vehicle_command")
    rig.cmd("start", "-m", MIXER)
    rig.run_ms(500)
    assert "in-air restart" in rig.dmesg()
    # PX4's sequence: nothing is asked before the commander has published actuator_armed
    assert sub.last is None
    assert regs.arming & ArmingA.FMU_ARMED  # held meanwhile
    assert not rig.io.writes_to(PageNo.RC_CONFIG)  # ignored by an IO with safety off
    rig.publish("actuator_armed", armed=False, ready_to_arm=False)
    rig.run_ms(250)                                 # the next arming check (every 200 ms)
    cmd = sub.last
    assert cmd is not None and cmd.command == 400 and cmd.param1 == 1.0
    assert cmd.param2 == 21196                      # flying: no preflight checks
    asked = sub.publish_count
    rig.run_ms(400)
    assert sub.publish_count > asked                # asked again until armed
    rig.publish("actuator_armed", armed=True, ready_to_arm=True)
    rig.run_ms(1500)
    assert regs.arming & ArmingA.FMU_ARMED
    assert "armed again" in rig.dmesg()


def test_fmu_restart_in_air_without_rearm_disarms_the_io_after_2_s_of_asking():
    rig = make_rig(start=False)
    rig.io.regs.arming = ArmingA.FMU_ARMED | ArmingA.INAIR_RESTART_OK
    rig.cmd("start")
    rig.publish("actuator_armed", armed=False)
    rig.run_ms(1900)
    assert rig.io.regs.arming & ArmingA.FMU_ARMED
    rig.run_ms(600)
    assert not rig.io.regs.arming & ArmingA.FMU_ARMED
    assert "failed to recover from in-air restart (not armed)" in rig.dmesg()


def test_fmu_restart_in_air_without_a_commander_gives_up_after_3_s():
    rig = make_rig(start=False)
    rig.io.regs.arming = ArmingA.FMU_ARMED | ArmingA.INAIR_RESTART_OK
    sub = rig.platform.orb.node("vehicle_command")
    rig.cmd("start")
    rig.run_ms(2900)
    assert rig.io.regs.arming & ArmingA.FMU_ARMED
    rig.run_ms(600)
    assert not rig.io.regs.arming & ArmingA.FMU_ARMED
    assert sub.last is None
    assert "failed to recover from in-air restart (no commander)" in rig.dmesg()


def test_stop_and_start_again():
    rig = make_rig()
    assert rig.cmd("stop") == 0
    n = len(rig.io.requests)
    rig.run_ms(100)
    assert len(rig.io.requests) == n
    assert rig.cmd("start") == 0
    rig.run_ms(60)
    assert rig.driver.state == "running"
    assert rig.cmd("mixer", MIXER) == 0
    rig.run_ms(30)
    assert rig.driver.mixer_ok


# -- across the lockstep (two boards, one quantum of wire latency) ---------------------------

@pytest.mark.parametrize("quantum_us", [100, 1000])
def test_lockstep_quantum_and_the_link(quantum_us, capsys):
    """Printed: what one lockstep quantum of latency per direction does to the link."""
    from board.wiring import PIXHAWK1
    from hil.orchestrator import BoardSpec, Orchestrator

    wires = [w for w in PIXHAWK1 if {w.src[0], w.dst[0]} == {"fmu", "io"}
             and "link" in w.src[1]]
    boards = {"fmu": BoardSpec("tests.drivers.px4io_fake_io:fmu_board_with_px4io"),
              "io": BoardSpec("ioproc.board:IoV2Board")}
    with Orchestrator(boards, wires, quantum_ns=quantum_us * 1000, mode="local") as orch:
        orch.start()
        orch.run(duration_ns=1_500_000_000)
        dmesg = "\n".join(text for _, _, _, text in orch.call("fmu", "dmesg"))
        st = orch.call("io", "status")
        perf = orch.handles["fmu"].board.platform.perf  # in-process: for the printout only
        txns = perf.find("px4io: io_txns")
        controls = perf.find("px4io: controls").events
        polls = perf.find("px4io: poll").events
    assert "IO ready" in dmesg and "MIXER_OK" in st["flag_names"], dmesg
    with capsys.disabled():
        print(f"\nquantum {quantum_us} us: {st['link']['packets']} packets in 1.5 s, "
              f"transaction {txns.mean_us:.0f} us avg (max {txns.max_us:.0f}), "
              f"{controls} controls writes (400 Hz offered), {polls} status polls")
