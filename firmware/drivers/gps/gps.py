"""u-blox GPS driver on a serial port, in the shape of PX4's gps module with its UBX helper.

PX4 runs this as a task that blocks in poll() with timeouts. Here it is a work item on the
serial port's work queue ("wq:ttyS3" for GPS1); the blocking sequence is written as a
generator (:meth:`GpsDriver._main`) that yields what it waits for (an ACK, a message, a
silence, data) with a deadline in virtual time. Each yield ends a run: the driver is woken by
the UART's IDLE interrupt when bytes have arrived, or by its deadline, reads what arrived,
feeds the parser and resumes the generator. That keeps PX4's step-by-step configuration
readable while the board stays event driven and deterministic.

Configuration follows PX4 (reference sensors.md 8.4): scan the baud rates, try CFG-VALSET
(an M8 NAKs it), CFG-PRT at the scanned rate until one is acknowledged, move the receiver to
38400, identify it with MON-VER, move a u-blox 8 to 115200, then CFG-RATE, CFG-NAV5, CFG-GNSS
(optional) and CFG-MSG for each output, each acknowledged within 250 ms or the whole sequence
starts again. Then NAV-PVT is published as ``sensor_gps``; no NAV-PVT for 1 s means the
receiver is gone or reset, and the driver goes back to configuring it.
"""

from __future__ import annotations

import calendar
import math
from collections.abc import Generator
from dataclasses import dataclass
from board.uart import Uart, UartConfig
from firmware.drivers.device import BUS_TYPE_SERIAL, DeviceId, SensorDriver
from firmware.drivers.gps import ubx
from firmware.drivers.gps.ubx import MonVer, NavPvt, UbxParser
from firmware.platform import Platform
from firmware.platform.perf import PC_COUNT
from firmware.platform.uorb import Publication

__all__ = ["DEVTYPE_UBX", "DEVTYPE_UBX_8", "GpsDriver"]

# PX4 drv_sensor.h device types of u-blox receivers [?: values not confirmed in the reference]
DEVTYPE_UBX, DEVTYPE_UBX_6, DEVTYPE_UBX_7, DEVTYPE_UBX_8, DEVTYPE_UBX_9 = 0xA8, 0xA9, 0xAA, \
    0xAB, 0xAC
_HW_BOARDS = {"00040007": (6, DEVTYPE_UBX_6), "00070000": (7, DEVTYPE_UBX_7),
              "00080000": (8, DEVTYPE_UBX_8), "00190000": (9, DEVTYPE_UBX_9)}


@dataclass
class _Wait:
    """What the configuration generator waits for, and until when."""

    kind: str                      # "sleep", "ack", "msg" or "data"
    deadline_us: int
    key: tuple[int, int] = (0, 0)  # (class, id) acknowledged or expected
    result: bool | None = None     # True: ACK / message seen, False: NAK


class GpsDriver(SensorDriver):
    """u-blox receiver on a UART: auto-baud, configuration, NAV-PVT -> ``sensor_gps``."""

    BAUD_RATES = (38400, 57600, 9600, 115200, 230400, 460800, 921600)
    VALSET_TIMEOUT_US = 2_000_000
    CONFIG_TIMEOUT_US = 250_000
    FLUSH_US = 20_000
    DATA_TIMEOUT_US = 1_000_000
    #: Position change between two fixes beyond what the velocity explains that is reported.
    JUMP_REPORT_M = 10.0
    JAMMING_REPORT = 80
    EPH_DEGRADED_M = 5.0

    def __init__(self, platform: Platform, uart: Uart, name: str = "gps", device_index: int = 0,
                 *, tty: str = "ttyS3", rate_ms: int = 200, dyn_model: int = 8,
                 gnss_systems: int = 0, sat_info: bool = False) -> None:
        super().__init__(platform, name, f"wq:{tty}")
        # Set per instance: compiled by mypyc, a class-level override of WorkItem's default
        # is not seen, and the compiled tier modelled the driver's runs as free (cpuload
        # showed it: 1.1 ms less busy time on wq:ttyS3 in 3 s than the pure modules).
        self.cpu_cost_ns = 40_000
        self.uart = uart
        self.device_index = device_index
        self.rate_ms = rate_ms
        self.dyn_model = dyn_model
        self.gnss_systems = gnss_systems
        self.sat_info = sat_info
        self.bus = int(tty[-1]) if tty[-1].isdigit() else 0
        self.device_id = DeviceId(BUS_TYPE_SERIAL, self.bus, 0, DEVTYPE_UBX)
        self.perf_bad_checksum = self.perf_alloc(PC_COUNT, "bad checksum")
        self.perf_timeouts = self.perf_alloc(PC_COUNT, "timeouts")
        self.parser = UbxParser()
        self.configured = False
        self.board: int | None = None
        self.mon_ver: MonVer | None = None
        self.baud = 0
        self.publish_count = 0
        self.last_pvt: NavPvt | None = None
        self._wait: _Wait | None = None
        self._proc: Generator[_Wait, bool | None, None] | None = None
        self._pub: Publication | None = None  # advertised with the first fix
        self._msg = platform.orb.new("sensor_gps")
        self._msg.heading = self._msg.heading_offset = math.nan
        self._last_pvt_us = 0
        self._seen_bad = 0
        self._sweeps = 0
        self._fix_ok = False
        self._jammed = False
        self._degraded = False

    # -- life cycle ------------------------------------------------------------------------

    def probe(self) -> str | None:
        """A serial receiver cannot be probed before the baud rate is known: configuration
        is the detection, so starting always succeeds."""
        return None

    def _start(self) -> None:
        self.uart.on_idle(self._on_idle)
        self._proc = self._main()
        self._wait = next(self._proc)
        self.schedule_now()

    def stop(self) -> None:
        self.uart.on_idle(None)
        super().stop()
        self._proc = None

    def _on_idle(self, t_ns: int) -> None:
        """UART IDLE interrupt: a burst has ended, wake the work item to read it."""
        if self.running:
            self.schedule_now()

    def status(self) -> str:
        state = "configured" if self.configured else "configuring"
        board = f"u-blox {self.board}" if self.board else "unknown receiver"
        lines = [super().status(),
                 f"  {state}, {board}, {self.baud} baud, {self.publish_count} publications",
                 "  " + self.perf_bad_checksum.summary(), "  " + self.perf_timeouts.summary()]
        return "\n".join(lines)

    # -- one run: read, parse, advance the sequence ------------------------------------------

    def run(self) -> None:
        proc = self._proc
        if not self.running or proc is None:
            return
        self.perf_cycle.begin()
        data = self.uart.read()
        if data:
            for cls, msg_id, payload in self.parser.feed(data):
                self._on_message(cls, msg_id, payload)
            bad = self.parser.bad_checksum
            for _ in range(bad - self._seen_bad):
                self.perf_bad_checksum.count()
            self._seen_bad = bad
        self._advance(proc)
        self.perf_cycle.end()

    def _advance(self, proc: Generator[_Wait, bool | None, None]) -> None:
        """Step the configuration sequence ``proc`` past every wait that has ended."""
        now = self.platform.time_us()
        while self._wait is not None:
            w = self._wait
            if w.kind == "data":
                w.deadline_us = self._last_pvt_us + self.DATA_TIMEOUT_US
            if w.result is None and now < w.deadline_us:
                self.schedule_delayed(w.deadline_us - now)
                return
            self._wait = proc.send(w.result)  # the generator never returns

    # -- helpers the sequence uses -----------------------------------------------------------

    def _sleep(self, us: int) -> _Wait:
        return _Wait("sleep", self.platform.time_us() + us)

    def _send(self, data: bytes, ack: tuple[int, int] | None = None,
              timeout_us: int = CONFIG_TIMEOUT_US) -> _Wait:
        """Write a message; the wait ends with its ACK (True), NAK (False) or the timeout."""
        self.uart.write(data)
        key = ack if ack is not None else (0, 0)
        return _Wait("ack" if ack is not None else "sleep",
                     self.platform.time_us() + timeout_us, key)

    def _set_baud(self, baud: int) -> None:
        self.baud = baud
        self.uart.config = UartConfig(baud)

    def _flush(self) -> None:
        self.uart.reset_input_buffer()
        self.uart.take_errors()
        self.parser.reset()

    # -- the sequence ------------------------------------------------------------------------

    def _main(self) -> Generator[_Wait, bool | None, None]:
        while True:
            if (yield from self._configure()):
                yield from self._receive()
            else:
                self._sweeps += 1
                if self._sweeps == 1:
                    self.platform.warn(self.name, "no u-blox receiver answering, still trying")

    def _configure(self) -> Generator[_Wait, bool | None, bool]:
        self.configured = False
        self.device_id = DeviceId(BUS_TYPE_SERIAL, self.bus, 0, DEVTYPE_UBX)
        for baud in self.BAUD_RATES:
            self._set_baud(baud)
            self._flush()
            yield self._sleep(self.FLUSH_US)
            self._flush()
            r = yield self._send(ubx.cfg_valset_uart1(), (ubx.CLS_CFG, ubx.ID_CFG_VALSET),
                                 self.VALSET_TIMEOUT_US)
            if r is True:
                self.platform.warn(self.name, "receiver accepts CFG-VALSET (protocol >= 27): "
                                              "not supported by this driver, using CFG-PRT")
            r = yield self._send(ubx.cfg_prt(baud), (ubx.CLS_CFG, ubx.ID_CFG_PRT))
            if r is not True:
                continue
            ok = yield from self._identify_and_set_rates()
            return ok
        return False

    def _switch(self, baud: int) -> Generator[_Wait, bool | None, None]:
        """Move the receiver to ``baud``: its ACK may come at either rate, so none is needed."""
        yield self._send(ubx.cfg_prt(baud))
        self._set_baud(baud)
        yield self._sleep(self.FLUSH_US)
        self._flush()

    def _identify_and_set_rates(self) -> Generator[_Wait, bool | None, bool]:
        yield from self._switch(38400)
        self.uart.write(ubx.frame(ubx.CLS_MON, ubx.ID_MON_VER))
        r = yield _Wait("msg", self.platform.time_us() + self.CONFIG_TIMEOUT_US,
                        (ubx.CLS_MON, ubx.ID_MON_VER))
        if r is not True:
            self.perf_timeouts.count()
            self.platform.warn(self.name, "no MON-VER answer, restarting configuration")
            return False
        if self.board == 8:
            yield from self._switch(115200)
        steps = [("CFG-RATE", ubx.cfg_rate(self.rate_ms), ubx.ID_CFG_RATE),
                 ("CFG-NAV5", ubx.cfg_nav5(self.dyn_model), ubx.ID_CFG_NAV5)]
        if self.gnss_systems:
            steps.append(("CFG-GNSS", ubx.cfg_gnss(self.gnss_systems), ubx.ID_CFG_GNSS))
        outputs = [("NAV-PVT", ubx.CLS_NAV, ubx.ID_NAV_PVT, 1),
                   ("NAV-STATUS", ubx.CLS_NAV, ubx.ID_NAV_STATUS, 1),
                   ("NAV-DOP", ubx.CLS_NAV, ubx.ID_NAV_DOP, 1),
                   ("NAV-SVINFO", ubx.CLS_NAV, ubx.ID_NAV_SVINFO, 5 if self.sat_info else 0),
                   ("MON-HW", ubx.CLS_MON, ubx.ID_MON_HW, 1)]
        steps += [(f"CFG-MSG {n}", ubx.cfg_msg(c, i, rate), ubx.ID_CFG_MSG)
                  for n, c, i, rate in outputs]
        for what, msg, msg_id in steps:
            r = yield self._send(msg, (ubx.CLS_CFG, msg_id))
            if r is not True:
                if r is None:
                    self.perf_timeouts.count()
                self.platform.warn(self.name, f"{what} {'NAK' if r is False else 'timeout'}, "
                                              "restarting configuration")
                return False
        return True

    def _receive(self) -> Generator[_Wait, bool | None, None]:
        self.configured = True
        self._sweeps = 0
        self._last_pvt_us = self.platform.time_us()
        board = f"u-blox {self.board}" if self.board else "u-blox (unknown model)"
        self.platform.info(self.name, f"{board} configured at {self.baud} baud, "
                                      f"{1000 // self.rate_ms} Hz")
        yield _Wait("data", 0)
        self.perf_timeouts.count()
        self.configured = False
        self._fix_ok = False
        self.platform.warn(self.name, f"no data for {self.DATA_TIMEOUT_US // 1000} ms, "
                                      "reconfiguring the receiver")

    # -- messages ----------------------------------------------------------------------------

    def _on_message(self, cls: int, msg_id: int, payload: bytes) -> None:
        w = self._wait
        if cls == ubx.CLS_ACK and len(payload) == 2:
            if w is not None and w.kind == "ack" and tuple(payload) == w.key:
                w.result = msg_id == ubx.ID_ACK_ACK
            return
        if cls == ubx.CLS_MON and msg_id == ubx.ID_MON_VER:
            self._on_mon_ver(payload)
            if w is not None and w.kind == "msg" and w.key == (cls, msg_id):
                w.result = True
            return
        if not self.configured:
            return
        if cls == ubx.CLS_NAV and msg_id == ubx.ID_NAV_PVT:
            pvt = NavPvt.decode(payload)
            if pvt is not None:
                self._publish(pvt)
        elif cls == ubx.CLS_NAV and msg_id == ubx.ID_NAV_DOP and len(payload) == 18:
            self._msg.vdop = int.from_bytes(payload[10:12], "little") * 0.01
            self._msg.hdop = int.from_bytes(payload[12:14], "little") * 0.01
        elif cls == ubx.CLS_MON and msg_id == ubx.ID_MON_HW and len(payload) in (60, 68):
            self._on_mon_hw(payload)

    def _on_mon_ver(self, payload: bytes) -> None:
        ver = MonVer.decode(payload)
        if ver is None:
            return
        self.mon_ver = ver
        # As in PX4, the model is known only once an extension string follows the hw field.
        if not ver.extensions:
            self.board = None
            return
        board, devtype = _HW_BOARDS.get(ver.hw, (None, DEVTYPE_UBX))
        self.board = board
        self.device_id = DeviceId(BUS_TYPE_SERIAL, self.bus, 0, devtype)
        wanted = [e for e in ver.extensions if e.startswith(("FWVER=", "PROTVER=", "MOD="))]
        self.platform.info(self.name, f"u-blox hw {ver.hw} sw '{ver.sw}' {' '.join(wanted)}")

    def _on_mon_hw(self, p: bytes) -> None:
        msg = self._msg
        msg.noise_per_ms = int.from_bytes(p[16:18], "little")
        msg.automatic_gain_control = int.from_bytes(p[18:20], "little")
        jam = p[45]
        msg.jamming_indicator = jam
        if not self._jammed and jam > self.JAMMING_REPORT:
            self._jammed = True
            self.platform.warn(self.name, f"jamming detected (indicator {jam})")
        elif self._jammed and jam < self.JAMMING_REPORT // 2:
            self._jammed = False
            self.platform.info(self.name, f"jamming over (indicator {jam})")

    def _publish(self, pvt: NavPvt) -> None:
        now = self.platform.time_us()
        msg = self._msg
        prev = self.last_pvt
        prev_us = self._last_pvt_us
        self._last_pvt_us = now
        self.last_pvt = pvt
        fix_ok = bool(pvt.flags & 0x01)
        fix_type = 0
        if fix_ok:
            fix_type = pvt.fix_type
            if pvt.flags & 0x02:
                fix_type = 4
            carr = pvt.flags >> 6 & 0x3
            if carr:
                fix_type = 4 + carr
        msg.timestamp = now
        msg.timestamp_sample = now
        msg.device_id = self.device_id.value
        msg.lat, msg.lon = pvt.lat_e7, pvt.lon_e7
        msg.alt, msg.alt_ellipsoid = pvt.hmsl_mm, pvt.height_mm
        msg.latitude_deg = pvt.lat_e7 * 1e-7
        msg.longitude_deg = pvt.lon_e7 * 1e-7
        msg.altitude_msl_m = pvt.hmsl_mm * 1e-3
        msg.altitude_ellipsoid_m = pvt.height_mm * 1e-3
        msg.fix_type = fix_type
        msg.satellites_used = pvt.num_sv
        msg.eph = pvt.h_acc_mm * 1e-3
        msg.epv = pvt.v_acc_mm * 1e-3
        msg.s_variance_m_s = pvt.s_acc_mm_s * 1e-3
        msg.c_variance_rad = math.radians(pvt.head_acc_e5 * 1e-5)
        msg.vel_m_s = pvt.g_speed_mm_s * 1e-3
        msg.vel_n_m_s = pvt.vel_n_mm_s * 1e-3
        msg.vel_e_m_s = pvt.vel_e_mm_s * 1e-3
        msg.vel_d_m_s = pvt.vel_d_mm_s * 1e-3
        msg.cog_rad = math.remainder(math.radians(pvt.head_mot_e5 * 1e-5), math.tau)
        msg.vel_ned_valid = True
        msg.time_utc_usec = self._utc_us(pvt)
        msg.timestamp_time_relative = 0
        pub = self._pub
        if pub is None:
            pub = self._pub = self.advertise("sensor_gps", self.device_index)
        pub.publish(msg)
        self.publish_count += 1
        self.perf_interval.count()
        self._report(pvt, fix_ok, prev, prev_us, now)

    @staticmethod
    def _utc_us(pvt: NavPvt) -> int:
        """UTC of the fix in us since 1970, only when date, time and resolution are valid."""
        if pvt.valid & 0x07 != 0x07:
            return 0
        try:
            s = calendar.timegm((pvt.year, pvt.month, pvt.day, pvt.hour, pvt.minute, pvt.sec))
        except (ValueError, OverflowError):
            return 0
        return max(0, s * 1_000_000 + pvt.nano_ns // 1000)

    def _report(self, pvt: NavPvt, fix_ok: bool, prev: NavPvt | None, prev_us: int,
                now: int) -> None:
        """dmesg lines for what an operator must know: fix, accuracy, jumps."""
        name = self.name
        if fix_ok and not self._fix_ok:
            self.platform.info(name, f"3D fix, {pvt.num_sv} satellites, "
                                     f"eph {pvt.h_acc_mm / 1000:.1f} m")
        elif self._fix_ok and not fix_ok:
            self.platform.warn(name, "fix lost")
        if fix_ok and self._fix_ok and prev is not None:
            dn = (pvt.lat_e7 - prev.lat_e7) * 1e-7 * 111_320.0
            de = ((pvt.lon_e7 - prev.lon_e7) * 1e-7 * 111_320.0
                  * math.cos(math.radians(pvt.lat_e7 * 1e-7)))
            dt = max(0, now - prev_us) * 1e-6
            moved = math.hypot(dn - pvt.vel_n_mm_s * 1e-3 * dt, de - pvt.vel_e_mm_s * 1e-3 * dt)
            if moved > self.JUMP_REPORT_M:
                self.platform.warn(name, f"position jump of {moved:.1f} m")
        eph = pvt.h_acc_mm * 1e-3
        if fix_ok and not self._degraded and eph > self.EPH_DEGRADED_M:
            self._degraded = True
            self.platform.warn(name, f"accuracy degraded: eph {eph:.1f} m")
        elif fix_ok and self._degraded and eph < self.EPH_DEGRADED_M * 0.6:
            self._degraded = False
            self.platform.info(name, f"accuracy recovered: eph {eph:.1f} m")
        self._fix_ok = fix_ok
