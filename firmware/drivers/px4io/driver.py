"""The px4io task (E14): configure the IO, stream control groups, poll status and RC at 50 Hz.

The shape is the 2014 driver's ``task_main`` (io-and-rc.md §1.8): wait for
``actuator_controls_0`` (rate-limited by ``px4io limit``) or the next 20 ms status tick; write
each updated control group to the CONTROLS page; every 20 ms read STATUS (arming sync and IO
reboot detection), RAW_RC_INPUT (-> ``input_rc``) and SERVOS (-> ``actuator_outputs``); every
200 ms look at ``actuator_armed``/``vehicle_status`` and parameters and push what changed.

Beyond E14 (marked [model]): the 20 ms tick is kept on its cadence instead of restarting after
each poll; an IO that lost ARM_SYNC or FMU_INITIALIZED is taken for rebooted and configured
again (mixer, PWM, RC, arming) before safety is restored (§3.12); the protocol-version read is
retried for 700 ms (the recent driver's rule) because the IO's bootloader holds it for 200 ms.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from types import SimpleNamespace
from typing import TYPE_CHECKING, Any, Final

from board.uart import Uart, UartConfig
from firmware.drivers.px4io import config as cfg
from firmware.drivers.px4io.link import IoLink, IoThread, Txn
from firmware.drivers.px4io.motor_test import MotorTest
from firmware.drivers.px4io.report import status_lines
from firmware.platform.task import Poll, Sleep
from firmware.platform.uorb import SubscriptionInterval
from ioproc.protocol import (
    CONTROL_CHANNELS,
    ERA,
    FORCE_SAFETY_MAGIC,
    PROTOCOL_VERSION,
    Alarms,
    ArmingA,
    Config,
    PageNo,
    RawRc,
    RawRcFlags,
    Setup,
    Status,
    StatusFlags,
    float_to_reg,
)

if TYPE_CHECKING:
    from firmware.drivers.px4io.module import Px4ioModule

__all__ = ["IO_BAUD", "ORB_CHECK_INTERVAL_US", "POLL_INTERVAL_US", "Px4ioDriver"]

IO_BAUD: Final = 1_500_000
POLL_INTERVAL_US: Final = 20_000  #: status / RC / servo poll (E14 IO_POLL_INTERVAL)
ORB_CHECK_INTERVAL_US: Final = 200_000  #: arming and parameter check (E14 ORB_CHECK_INTERVAL)
GROUP_INTERVAL_US: Final = 33_000  #: actuator_controls_1..3 subscription interval (E14)
#: px4io task priority: SCHED_PRIORITY_ACTUATOR_OUTPUTS = max - 15
TASK_PRIORITY: Final = -15
PROTOCOL_RETRY_US: Final = 700_000
PROTOCOL_RETRY_GAP_US: Final = 2_000
#: in-air restart (PX4 px4io): wait this long for the commander's first actuator_armed ...
INAIR_WAIT_COMMANDER_US: Final = 3_000_000
#: ... then ask it to arm (again at every arming check) for this long before giving up
INAIR_REARM_US: Final = 2_000_000
MIXER_CHUNK_TRIES: Final = 30  #: mixer_send retries per chunk, 333 us apart (§2.11)
MIXER_RETRY_GAP_US: Final = 333

# Plain-int copies of the bit enums: IntFlag arithmetic costs ~1 us a go in the 50 Hz path.
_SF: Final = SimpleNamespace(**{str(m.name): int(m) for m in StatusFlags})
_A: Final = SimpleNamespace(**{str(m.name): int(m) for m in ArmingA})
_AL: Final = SimpleNamespace(**{str(m.name): int(m) for m in Alarms})
_RC_OK: Final = int(RawRcFlags.RC_OK)
_RC_FAILSAFE: Final = int(RawRcFlags.FAILSAFE)
#: px4io_status boolean fields and the bit each one shows
_STATUS_BITS: Final = tuple((f"status_{n.lower()}", "status_flags", int(StatusFlags[n]))
                     for n in cfg.STATUS_FIELDS) + \
    tuple((f"alarm_{n.lower()}", "alarms", int(Alarms[n])) for n in cfg.ALARM_FIELDS) + \
    tuple((f"arming_{n.lower()}", "arming", int(ArmingA[n])) for n in cfg.ARMING_FIELDS)
#: SETUP_ARMING bits this driver owns (the IO sets FAILSAFE_CUSTOM and ALWAYS_PWM_ENABLE).
_ARMING_OWNED: Final = (_A.FMU_ARMED | _A.IO_ARM_OK | _A.LOCKDOWN | _A.FORCE_FAILSAFE
                 | _A.OVERRIDE_IMMEDIATE
                 | _A.MANUAL_OVERRIDE_OK | _A.INAIR_RESTART_OK | _A.TERMINATION_FAILSAFE)
_ALARM_TEXT = ((_AL.FMU_LOST, "FMU lost (no controls for 500 ms)"),
               (_AL.RC_LOST, "RC lost"), (_AL.PWM_ERROR, "PWM rate error"),
               (_AL.VSERVO_FAULT, "servo rail fault"), (_AL.TEMPERATURE, "temperature"))
#: input_rc.input_source from STATUS_FLAGS, first match wins (io-and-rc.md §9.1)
_RC_SOURCES = ((_SF.RC_PPM, 2), (_SF.RC_DSM, 3), (_SF.RC_SBUS, 4), (_SF.RC_ST24, 5),
               (_SF.RC_SUMD, 11))
_VEHICLE_CMD_ARM: Final = 400
_FORCE_ARM_MAGIC: Final = 21196  #: vehicle_command param2: arm without the preflight checks
_VEHICLE_TYPE_FIXED_WING: Final = 2


class Px4ioDriver:
    """Everything the px4io module does on the link; the module is its shell face."""

    def __init__(self, module: Px4ioModule, uart: Uart, mixer: str | None,
                 update_rate_hz: int) -> None:
        self.m = module
        self.platform = module.platform
        self.uart = uart
        uart.config = UartConfig(baud=IO_BAUD)  # BRR for 1.5 Mbit/s, 8N1 (§1.1)
        self.link = IoLink(uart, module.perf_alloc, self._log)
        self.thread = IoThread(self.platform, uart, module.name, self._main, TASK_PRIORITY)
        self.state = "starting"
        self.fail_reason = ""
        self.config: dict[str, int] = {}
        self.status_flags = 0
        self.alarms = 0
        self._alarms_reported = 0
        self._alarms_stale = False
        self.arming = 0
        self.freemem = 0
        self.vservo_mv = 0
        self.vrssi_mv = 0
        self.servos: list[int] = []
        self.pwm_disarmed: list[int] = []
        self.pwm_failsafe: list[int] = []
        self.rc_values: list[int] = []
        self.rc_count = 0
        self.rc_flags = 0
        self.mixer_name = mixer
        self.mixer_ok = False
        self.io_reboots = 0
        self.inair_restart = False
        self._inair_start_us = 0
        self._inair_asked_us: int | None = None
        self.inair_restart_ok = False
        self.termination_failsafe = False
        self.update_rate_hz = 0
        self._have_status = False
        self._rc_seen = False
        self._rc_last_signal_us = 0
        self._sent: dict[str, Any] = {}
        self._pending: deque[tuple[str, Callable[[], Txn]]] = deque()
        orb = self.platform.orb
        self.sub_controls = [SubscriptionInterval(orb, f"actuator_controls_{g}", 0)
                             for g in range(4)]
        for sub in self.sub_controls[1:]:
            sub.interval_us = GROUP_INTERVAL_US
        module.subscriptions.extend(self.sub_controls)
        self.set_update_rate(update_rate_hz)
        self.sub_armed = module.subscribe("actuator_armed")
        self.sub_vstatus = module.subscribe("vehicle_status")
        self.sub_params = module.subscribe("parameter_update")
        self.pub_rc = module.advertise("input_rc")
        self.pub_outputs = module.advertise("actuator_outputs")
        self.pub_status = module.advertise("px4io_status")
        self.msg_rc = orb.new("input_rc")
        self.msg_outputs = orb.new("actuator_outputs")
        self.msg_status = orb.new("px4io_status")
        self.pc_controls = module.perf_alloc("interval", "controls")
        self.pc_poll = module.perf_alloc("interval", "poll")
        self.motor_test = MotorTest(self)

    # -- life cycle and commands --------------------------------------------------------------

    def start(self) -> None:
        self.thread.start()

    def stop(self) -> None:
        self.thread.stop()

    def set_update_rate(self, rate_hz: int) -> None:
        """``px4io limit``: E14 turns Hz into a whole-ms subscription interval, 2..100 ms."""
        interval_ms = max(2, min(100, 1000 // max(1, rate_hz)))
        self.sub_controls[0].interval_us = interval_ms * 1000
        self.update_rate_hz = rate_hz

    def request(self, what: str, op: Callable[[], Txn]) -> None:
        """Queue IO transactions for the task (shell commands cannot block on the link)."""
        self._pending.append((what, op))

    def status_lines(self) -> list[str]:
        return status_lines(self)

    def _log(self, level: str, text: str) -> None:
        getattr(self.m, level)(text)

    def _now(self) -> int:
        return self.platform.time_us()

    def _param(self, name: str, default: float) -> float:
        params = self.m.system.params
        if params is None or name not in params:
            return default
        return params[name]

    # -- the task -----------------------------------------------------------------------------

    def _main(self, thread: IoThread) -> Txn:
        ok = yield from self._init()
        if not ok:
            self.state = "failed"
            self.m.error(self.fail_reason)
            self.m.init_failed()
            return
        self.state = "running"
        next_poll = next_orb = self._now()
        subs = self.sub_controls
        while not thread.should_exit:
            yield Poll(subs[:1], max(0, next_poll - self._now()))
            for group, sub in enumerate(subs):
                if not sub.updated():
                    continue
                if self.motor_test.active():
                    sub.update()  # taken, not sent: CONTROLS would clear the test's RAW_PWM
                else:
                    yield from self._send_controls(group, sub)
            now = self._now()
            if now >= next_poll:
                next_poll = next_poll + POLL_INTERVAL_US if now - next_poll < \
                    POLL_INTERVAL_US else now + POLL_INTERVAL_US
                armed = self.sub_armed.node.last
                self.motor_test.poll(now, armed is not None and bool(armed.armed))
                yield from self.motor_test.write(now)
                yield from self._poll_io()
            if now >= next_orb:
                next_orb = now + ORB_CHECK_INTERVAL_US
                yield from self._check_orb()
            while self._pending:
                what, op = self._pending.popleft()
                self.link.last_error = ""
                ok = yield from op()
                if ok is False and self.link.last_error:
                    # a link failure the operation did not explain (it reports its own refusals)
                    self.m.warn(f"{what} failed: {self.link.last_error}")

    def _fail(self, reason: str) -> bool:
        self.fail_reason = reason
        return False

    def _init(self) -> Txn:
        """Read CONFIG, refuse a wrong protocol, recover an in-air restart, configure."""
        link = self.link
        deadline = self._now() + PROTOCOL_RETRY_US
        while True:
            regs = yield from link.read(PageNo.CONFIG, Config.PROTOCOL_VERSION, 1)
            if regs is not None or self._now() >= deadline:
                break
            yield Sleep(PROTOCOL_RETRY_GAP_US)
        if regs is None:
            return self._fail(f"IO not installed: no answer to the protocol version read on "
                              f"{self.uart.name} ({link.last_error})")
        want = PROTOCOL_VERSION[ERA]
        if regs[0] != want:
            return self._fail(f"IO protocol version {regs[0]}, this driver speaks version "
                              f"{want} ({ERA.value}): wrong IO firmware, IO not used")
        self.config["protocol"] = regs[0]
        for key, reg in cfg.CONFIG_READS:
            regs = yield from link.read(PageNo.CONFIG, reg, 1)
            if regs is None:
                return self._fail(f"config read error: CONFIG register {reg} "
                                  f"({link.last_error})")
            self.config[key] = regs[0]
        problem = cfg.check_config(self.config)
        if problem:
            return self._fail(f"config read error: {problem}")
        link.max_regs = min(link.max_regs, (self.config["max_transfer"] - 2) // 2)
        yield from link.write(PageNo.STATUS, Status.ALARMS, [0xFFFF])  # stale boot latches
        regs = yield from link.read(PageNo.STATUS, Status.FREEMEM, 4)
        if regs is not None:
            self.freemem, _, self.status_flags, self.alarms = regs
        regs = yield from link.read(PageNo.SETUP, Setup.ARMING, 1)
        arming = regs[0] if regs is not None else 0
        if arming & _A.INAIR_RESTART_OK and arming & _A.FMU_ARMED:
            self.inair_restart = self.inair_restart_ok = True
            self._inair_start_us = self._now()
            self._inair_asked_us = None
            self.arming = arming
            self.m.warn("IO is armed with INAIR_RESTART_OK: recovering from an FMU in-air "
                        "restart")
        else:
            v = yield from link.modify(PageNo.SETUP, Setup.ARMING, _A.FMU_ARMED
                                       | _A.INAIR_RESTART_OK | _A.MANUAL_OVERRIDE_OK
                                       | _A.ALWAYS_PWM_ENABLE, 0)
            self.arming = v if v is not None else arming
        yield from self._configure()
        c = self.config
        self.m.info(f"IO ready: protocol {c['protocol']}, hardware {c['hardware']}, "
                    f"bootloader {c['bootloader']}, {c['actuators']} outputs, "
                    f"{c['rc_inputs']} RC inputs, mixer "
                    f"{self.mixer_name or 'none'}{' OK' if self.mixer_ok else ''}")
        return True

    def _request_arm(self) -> None:
        """The in-air restart's arm request. The vehicle is flying: the commander must not hold
        it to its preflight checks (PX4's IN_AIR_RESTORE arming state skipped them), so the
        request carries the force-arm magic."""
        pub = self.m.advertise("vehicle_command")
        cmd = self.platform.orb.new("vehicle_command", timestamp=self._now(),
                                    command=_VEHICLE_CMD_ARM, param1=1.0,
                                    param2=float(_FORCE_ARM_MAGIC))
        pub.publish(cmd)

    def _inair_pending(self, armed: Any) -> bool:
        """PX4's recovery sequence: wait for the commander to publish actuator_armed (3 s at
        most), then ask it to arm until it has (2 s at most); meanwhile the IO keeps
        FMU_ARMED. True while the IO's arming must be left alone."""
        now = self._now()
        if armed is not None and armed.armed:
            self.inair_restart = False
            self.m.info("in-air restart: armed again")
            return False
        if armed is None:
            if now - self._inair_start_us < INAIR_WAIT_COMMANDER_US:
                return True
            why = "no commander"
        else:
            if self._inair_asked_us is None:
                self._inair_asked_us = now
            if now - self._inair_asked_us < INAIR_REARM_US:
                self._request_arm()
                return True
            why = "not armed"
        self.inair_restart = False
        self.m.error(f"failed to recover from in-air restart ({why}), disarming the IO")
        return False

    def _configure(self) -> Txn:
        """Everything a fresh IO needs from the FMU; also run again after an IO reboot."""
        self._sent.clear()
        if not self.status_flags & _SF.SAFETY_OFF:  # the IO ignores RC_CONFIG with safety off
            yield from self._send_rc_config()
        yield from self.link.write(PageNo.SETUP, Setup.FEATURES, [cfg.FEATURES])
        yield from self._send_rates()
        if self.mixer_name:
            yield from self._upload_mixer(self.mixer_name)
        yield from self._send_pwm()
        yield from self._send_arming()
        if int(self._param("CBRK_IO_SAFETY", 0)) == cfg.CBRK_IO_SAFETY_KEY:
            yield from self.link.write(PageNo.SETUP, Setup.FORCE_SAFETY_OFF,
                                       [FORCE_SAFETY_MAGIC])
        return True

    # -- configuration pieces -----------------------------------------------------------------

    def _send_rc_config(self) -> Txn:
        """RC_CONFIG per channel, then check INIT_OK (E14 io_set_rc_config)."""
        table = cfg.rc_config_table(self._param, min(self.config["rc_inputs"], 18))
        self._sent["rc"] = table
        for ch, regs in enumerate(table):
            if not (yield from self.link.write(PageNo.RC_CONFIG, ch * 6, regs)):
                self.m.error(f"RC config write for channel {ch + 1} failed: "
                             f"{self.link.last_error}")
                return False
            flags = yield from self.link.read(PageNo.STATUS, Status.FLAGS, 1)
            if flags is not None and not flags[0] & _SF.INIT_OK:
                self.m.error(f"IO rejected the RC config of channel {ch + 1}: {regs}")
                return False
        return True

    def _send_rates(self) -> Txn:
        """Default rate, alternate rate, then the mask (the IO programs with stored rates)."""
        rate = int(self._param("PWM_RATE", 400))
        mask = cfg.output_mask(int(self._param("PWM_OUT", 1234)))
        self._sent["rates"] = (rate, mask)
        link = self.link
        ok = yield from link.write(PageNo.SETUP, Setup.PWM_DEFAULTRATE, [cfg.DEFAULT_RATE_HZ])
        ok &= yield from link.write(PageNo.SETUP, Setup.PWM_ALTRATE, [rate])
        ok &= yield from link.write(PageNo.SETUP, Setup.PWM_RATES, [mask])
        return ok

    def _send_pwm(self) -> Txn:
        """CONTROL_MIN/MAX, FAILSAFE (only if set) and DISARMED pages from the parameters."""
        n = self.config["actuators"] if self.config.get("actuators") else 8
        n = min(n, 8)
        pages = cfg.pwm_pages(self._param, n)
        self._sent["pwm"] = pages
        link = self.link
        ok = True
        for page, values in pages:
            ok &= yield from link.write(page, 0, values)
        regs = yield from link.read(PageNo.DISARMED_PWM, 0, n)
        if regs is not None:
            self.pwm_disarmed = regs
        regs = yield from link.read(PageNo.FAILSAFE_PWM, 0, n)
        if regs is not None:
            self.pwm_failsafe = regs
        return ok

    def _upload_mixer(self, name: str) -> Txn:
        """mixer_send: the filtered file in page-52 chunks, then check MIXER_OK."""
        self.mixer_name = name
        self.mixer_ok = False
        try:
            chunks = cfg.mixer_chunks(self.m.system, name, self.config.get("max_transfer", 64))
        except (OSError, ValueError) as exc:
            self.m.error(f"mixer {name}: {exc}")
            return False
        if self.status_flags & _SF.SAFETY_OFF:
            self.m.warn(f"mixer {name} not sent: IO safety is off (E14 refuses mixer changes)")
            return False
        for i, chunk in enumerate(chunks):
            for _ in range(MIXER_CHUNK_TRIES + 1):
                ok = yield from self.link.write(PageNo.MIXERLOAD, 0, chunk)
                if ok:
                    break
                yield Sleep(MIXER_RETRY_GAP_US)
            if not ok:
                self.m.error(f"mixer {name}: chunk {i + 1}/{len(chunks)} not accepted "
                             f"({self.link.last_error})")
                return False
        flags = yield from self.link.read(PageNo.STATUS, Status.FLAGS, 1)
        if flags is None or not flags[0] & _SF.MIXER_OK:
            self.m.error(f"mixer {name}: rejected by the IO (MIXER_OK clear)")
            return False
        self.mixer_ok = True
        self.m.info(f"mixer {name} loaded ({len(chunks)} chunks)")
        return True

    def _send_arming(self) -> Txn:
        """SETUP_ARMING from actuator_armed, vehicle_status and the driver's own flags."""
        armed = self.sub_armed.copy()
        vstatus = self.sub_vstatus.copy()
        bits = 0
        if armed is not None:
            bits |= _A.FMU_ARMED if armed.armed else 0
            bits |= _A.IO_ARM_OK if armed.ready_to_arm else 0
            bits |= _A.LOCKDOWN if armed.lockdown or armed.manual_lockdown else 0
            bits |= _A.FORCE_FAILSAFE if armed.force_failsafe else 0
        if vstatus is not None and vstatus.vehicle_type == _VEHICLE_TYPE_FIXED_WING:
            bits |= _A.MANUAL_OVERRIDE_OK  # E14: override only for non-rotary-wing vehicles
        if int(self._param("IO_OVERRIDE_EN", 0)):
            # The emulator's opt-in: override allowed, and taken at once when the FMU is lost.
            bits |= _A.MANUAL_OVERRIDE_OK | _A.OVERRIDE_IMMEDIATE
        bits |= _A.INAIR_RESTART_OK if self.inair_restart_ok else 0
        bits |= _A.TERMINATION_FAILSAFE if self.termination_failsafe else 0
        if self.inair_restart and self._inair_pending(armed):
            return True  # keep FMU_ARMED on the IO until the commander re-arms
        v = yield from self.link.modify(PageNo.SETUP, Setup.ARMING, _ARMING_OWNED & ~bits,
                                        bits)
        if v is None:
            return False
        self.arming = v
        return True

    def _check_orb(self) -> Txn:
        if self.sub_armed.updated() or self.sub_vstatus.updated() or self.inair_restart:
            yield from self._send_arming()
        if self.sub_params.updated():
            self.sub_params.copy()
            yield from self._apply_param_changes()

    def _apply_param_changes(self) -> Txn:
        n = min(self.config.get("actuators", 8), 8)
        if cfg.rc_config_table(self._param, min(self.config["rc_inputs"], 18)) != \
                self._sent.get("rc"):
            yield from self._send_rc_config()
        rate = int(self._param("PWM_RATE", 400))
        if (rate, cfg.output_mask(int(self._param("PWM_OUT", 1234)))) != self._sent.get("rates"):
            yield from self._send_rates()
        if cfg.pwm_pages(self._param, n) != self._sent.get("pwm"):
            yield from self._send_pwm()

    # -- the 400 Hz and 50 Hz work ------------------------------------------------------------

    def _send_controls(self, group: int, sub: SubscriptionInterval) -> Txn:
        msg = sub.update()
        if msg is None:
            return
        if group == 0:
            self.pc_controls.count()
        n = min(self.config.get("controls", CONTROL_CHANNELS), CONTROL_CHANNELS)
        regs = [float_to_reg(v) for v in msg.control[:n]]
        yield from self.link.write(PageNo.CONTROLS, group * CONTROL_CHANNELS, regs)

    def _poll_io(self) -> Txn:
        self.pc_poll.count()
        regs = yield from self.link.read(PageNo.STATUS, Status.FLAGS, 6)
        if regs is not None:
            flags, alarms, _vbatt, _ibatt, self.vservo_mv, self.vrssi_mv = regs
            yield from self._handle_status(flags)
            yield from self._handle_alarms(alarms)
        yield from self._poll_rc()
        n = min(self.config.get("actuators", 8), 8)
        regs = yield from self.link.read(PageNo.SERVOS, 0, n)
        if regs is not None:
            self.servos = regs
            out = self.msg_outputs
            out.timestamp = self._now()
            out.noutputs = n
            out.output = [float(v) for v in regs] + [0.0] * (16 - n)
            self.pub_outputs.publish(out)
        self._publish_status()

    def _handle_status(self, flags: int) -> Txn:
        """Arming sync and reboot detection (io-and-rc.md §3.12)."""
        prev = self.status_flags
        rebooted = self._have_status and (
            (prev & _SF.ARM_SYNC and not flags & _SF.ARM_SYNC)
            or (prev & _SF.FMU_INITIALIZED and not flags & _SF.FMU_INITIALIZED))
        self._have_status = True
        self.status_flags = flags
        if rebooted:
            self.io_reboots += 1
            self.m.warn(f"IO reboot detected (STATUS_FLAGS 0x{prev:04X} -> 0x{flags:04X}): "
                        f"configuring it again")
            self.mixer_ok = False
            self._alarms_stale = True
            yield from self._configure()
            set_bits = _SF.ARM_SYNC | (prev & _SF.SAFETY_OFF)
            v = yield from self.link.modify(PageNo.STATUS, Status.FLAGS, 0, set_bits)
            if prev & _SF.SAFETY_OFF:
                self.m.warn("IO in-air restart: safety off restored")
        elif not flags & _SF.ARM_SYNC:
            v = yield from self.link.modify(PageNo.STATUS, Status.FLAGS, 0, _SF.ARM_SYNC)
        else:
            return
        if v is not None:
            self.status_flags = v

    def _handle_alarms(self, alarms: int) -> Txn:
        """Report each new alarm once; acknowledge it when the IO can latch it again.

        The IO re-latches FMU_LOST / RC_LOST on every pass while the condition lasts, and E14
        never clears them, so a second FMU stall would go unseen. [model] The driver writes
        the bit back (clearing it) once the condition is over (FMU_OK / RC_OK set again) and
        one-shot alarms (PWM_ERROR ...) right after reporting them.
        """
        if self._alarms_stale:  # latched by the IO's own boot: not news
            self._alarms_stale = False
            self.alarms, self._alarms_reported = alarms, 0
        new = alarms & ~self.alarms
        for bit, text in _ALARM_TEXT:
            if new & bit:
                self.m.warn(f"IO alarm: {text}")
        self._alarms_reported |= new
        self.alarms = alarms
        flags = self.status_flags
        ack = alarms & ~(_AL.FMU_LOST | _AL.RC_LOST)
        if flags & _SF.FMU_OK:
            ack |= alarms & _AL.FMU_LOST
        if flags & _SF.RC_OK:
            ack |= alarms & _AL.RC_LOST
        if not ack or not (yield from self.link.write(PageNo.STATUS, Status.ALARMS, [ack])):
            return
        self.alarms &= ~ack
        ended = ack & self._alarms_reported & (_AL.FMU_LOST | _AL.RC_LOST)
        self._alarms_reported &= ~ack
        if ended & _AL.FMU_LOST:
            self.m.info("IO: FMU controls arriving again")
        if ended & _AL.RC_LOST:
            self.m.info("IO: RC signal regained")

    def _poll_rc(self) -> Txn:
        """RAW_RC_INPUT header + 9 channels, the rest if more -> input_rc (§9.1)."""
        link = self.link
        regs = yield from link.read(PageNo.RAW_RC_INPUT, 0, RawRc.BASE + 9)
        if regs is None:
            return
        count = min(regs[RawRc.COUNT], 18)
        values = regs[RawRc.BASE:RawRc.BASE + min(count, 9)]
        if count > 9:
            more = yield from link.read(PageNo.RAW_RC_INPUT, RawRc.BASE + 9, count - 9)
            if more is None:
                return
            values += more
        flags = regs[RawRc.FLAGS]
        now = self._now()
        self.rc_count, self.rc_flags, self.rc_values = count, flags, values
        msg = self.msg_rc
        msg.timestamp = now
        msg.channel_count = count
        msg.rc_lost = not flags & _RC_OK
        msg.rc_failsafe = bool(flags & _RC_FAILSAFE)
        msg.rssi = regs[RawRc.NRSSI]
        msg.rc_ppm_frame_length = regs[RawRc.DATA]
        msg.rc_total_frame_count = regs[RawRc.FRAME_COUNT]
        msg.rc_lost_frame_count = regs[RawRc.LOST_FRAME_COUNT]
        msg.input_source = next((src for bit, src in _RC_SOURCES if self.status_flags & bit), 0)
        msg.values = list(values) + [0] * (18 - len(values))
        if not msg.rc_lost and not msg.rc_failsafe:
            self._rc_last_signal_us = now
        msg.timestamp_last_signal = self._rc_last_signal_us
        if flags & _RC_OK:
            self._rc_seen = True
        if self._rc_seen:  # E14 publishes once RC has been valid
            self.pub_rc.publish(msg)

    def _publish_status(self) -> None:
        m = self.msg_status
        m.timestamp = self._now()
        m.free_memory_bytes = self.freemem
        m.voltage_v = self.vservo_mv / 1000.0
        m.rssi_v = self.vrssi_mv / 1000.0
        for field, source, bit in _STATUS_BITS:
            setattr(m, field, bool(getattr(self, source) & bit))
        m.arming_fmu_prearmed = False  # no such bit in layout A
        m.pwm = cfg.pad8(self.servos)
        m.pwm_disarmed = cfg.pad8(self.pwm_disarmed)
        m.pwm_failsafe = cfg.pad8(self.pwm_failsafe)
        m.raw_inputs = list(self.rc_values) + [0] * (18 - len(self.rc_values))
        m.link_errors = self.link.failed_attempts
        m.io_reboots = self.io_reboots
        self.pub_status.publish(m)
