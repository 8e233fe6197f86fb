"""The logger module: uORB topics, console messages and parameters to ULog files on the SD card.

Shape of PX4's logger: a work item on ``wq:lp_default`` that polls its subscriptions at a fixed
interval, encodes every update into a bounded write buffer, and a writer that empties the buffer
onto the SD card. On the real board the writer is a thread limited by the card's throughput;
here it is modelled in virtual time: the buffer drains at ``sd_write_rate_bytes_s``. When a
sample does not fit, it is dropped and, once there is room again, an 'O' (dropout) message with
the length of the gap is written, as PX4 does. Definitions, subscriptions, parameter changes and
console messages are never dropped (PX4 writes those blocking).

Files are ``<log_root>/YYYY-MM-DD/HH_MM_SS.ulg``, named from the emulated UTC time (a given
epoch plus virtual time, or a callable such as GPS time), never from the host clock, so the same
inputs give byte-identical files.
"""

from __future__ import annotations

import datetime as _dt
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, BinaryIO

from firmware.modules.logger.profiles import LoggedTopic, get_profile
from firmware.modules.logger.ulog import UlogError, UlogWriter, formats_for
from firmware.platform.uorb import ORB_MULTI_MAX_INSTANCES, Subscription, SubscriptionInterval
from firmware.platform.workqueue import WorkItem
from firmware.version import NUTTX_VERSION, board_uid, os_version_word, software_hash, version_word

if TYPE_CHECKING:
    from firmware.platform import Platform

__all__ = ["DEFAULT_INFO", "DEFAULT_UTC_EPOCH_S", "Logger", "SdWriteBuffer", "log_path_for",
           "version_info"]

#: 2024-01-01T00:00:00Z: the emulated RTC's time at boot when nothing better is known
DEFAULT_UTC_EPOCH_S = 1_704_067_200

def version_info(version: str = "fmu-hil 0.1.0", hw_arch: str = "PX4_FMU_V2",
                 git_hash: str | None = None, board_name: str = "px4_fmu-v2") -> dict[str, Any]:
    """The info messages PX4's logger writes about the build (``write_version``), which Flight
    Review shows: software hash and release word, hardware, OS and its release word, toolchain,
    MCU and its unique ID (see :mod:`firmware.version` for what each is here and why). Fixed
    for a version and board, so the same seed still gives the same bytes."""
    return {
        "sys_name": "PX4",
        "ver_hw": hw_arch,
        "ver_sw": software_hash(version, git_hash),
        "ver_sw_release": (version_word(version), "uint32_t"),
        "sys_os_name": "NuttX",
        "sys_os_ver": ".".join(str(n) for n in NUTTX_VERSION),
        "sys_os_ver_release": (os_version_word(), "uint32_t"),
        "sys_toolchain": "CPython",
        "sys_toolchain_ver": f"{sys.version_info.major}.{sys.version_info.minor}",
        "sys_mcu": "STM32F42x, rev. 3",
        "sys_uuid": board_uid(board_name).hex().upper(),
    }


#: info messages of every file; values are str/int/float or (value, ulog type name)
DEFAULT_INFO: dict[str, Any] = version_info() | {"time_ref_utc": 0}

ARMING_STATE_ARMED = 2  # PX4 vehicle_status.arming_state when armed


def log_path_for(log_root: str | os.PathLike, utc_us: int) -> Path:
    """``<root>/YYYY-MM-DD/HH_MM_SS.ulg`` for an emulated UTC time (microseconds since 1970)."""
    t = _dt.datetime(1970, 1, 1, tzinfo=_dt.UTC) + _dt.timedelta(microseconds=utc_us)
    return Path(log_root) / t.strftime("%Y-%m-%d") / t.strftime("%H_%M_%S.ulg")


class SdWriteBuffer:
    """The logger's write buffer in front of the SD card, drained at a modelled throughput.

    ``write()`` always appends (the ULog writer's sink); the logger asks :meth:`fits` before
    writing anything it may drop. ``drain(now_us)`` moves the bytes the card could have taken
    since the previous drain into the file. A rate of 0 means an infinitely fast card.
    """

    def __init__(self, fileobj: BinaryIO, capacity_bytes: int, rate_bytes_s: int,
                 now_us: int) -> None:
        if capacity_bytes <= 0:
            raise ValueError(f"logger buffer must be positive, got {capacity_bytes} bytes")
        if rate_bytes_s < 0:
            raise ValueError(f"SD write rate must be >= 0 B/s, got {rate_bytes_s}")
        self.file = fileobj
        self.capacity = capacity_bytes
        self.rate = rate_bytes_s
        self.pending = bytearray()
        self.max_fill = 0
        self.written = 0
        self._last_us = now_us
        self._credit = 0   # byte-microseconds of throughput not yet used (integer: deterministic)

    def write(self, data: bytes) -> int:
        self.pending += data
        self.max_fill = max(self.max_fill, len(self.pending))
        return len(data)

    def fits(self, n: int) -> bool:
        return len(self.pending) + n <= self.capacity

    def drain(self, now_us: int) -> None:
        dt = now_us - self._last_us
        self._last_us = now_us
        if not self.pending:
            self._credit = 0
            return
        if self.rate == 0:
            self._flush(len(self.pending))
            return
        self._credit += self.rate * max(dt, 0)
        n = min(len(self.pending), self._credit // 1_000_000)
        self._credit -= n * 1_000_000
        self._flush(n)
        if not self.pending:
            self._credit = 0

    def _flush(self, n: int) -> None:
        if n <= 0:
            return
        self.file.write(bytes(self.pending[:n]))
        del self.pending[:n]
        self.written += n

    def flush(self) -> None:
        """Write everything buffered now (a blocking write, as for the file's header)."""
        self._flush(len(self.pending))
        self._credit = 0

    def close(self) -> None:
        """Write everything still buffered (PX4 flushes and fsyncs on stop) and close."""
        self.flush()
        self.file.close()


class _TopicSub:
    """One subscribed (topic, instance) and its ULog msg_id in the current file."""

    __slots__ = ("every", "instance", "msg_id", "sub", "topic")

    def __init__(self, topic: str, instance: int, sub: Subscription, every: bool) -> None:
        self.topic = topic
        self.instance = instance
        self.sub = sub
        self.every = every
        self.msg_id: int | None = None


class Logger(WorkItem):
    """The ``logger`` module. ``start()`` begins polling; files open at boot or at arming.

    ``params_provider()`` returns ``{name: int | float}`` (written at the start of each file and
    again, as changes, whenever ``parameter_update`` is published). ``is_armed()`` decides
    arming in mode "arm" when no ``vehicle_status`` topic with ``arming_state`` exists.
    """

    def __init__(self, platform: Platform, log_root: str | os.PathLike,
                 profile: str | list | dict = "default", mode: str = "boot", *,
                 params_provider: Callable[[], dict[str, int | float]] | None = None,
                 is_armed: Callable[[], bool] | None = None,
                 utc_epoch_s: int = DEFAULT_UTC_EPOCH_S,
                 utc_us: Callable[[], int] | None = None,
                 sd_write_rate_bytes_s: int = 400_000,
                 buffer_bytes: int = 12 * 1024,
                 interval_us: int = 3500,
                 sync_interval_us: int = 1_000_000,
                 info: dict[str, Any] | None = None) -> None:
        super().__init__(platform, "logger", "wq:lp_default")
        if mode not in ("boot", "arm"):
            raise ValueError(f"logger mode must be 'boot' or 'arm', got {mode!r}")
        if interval_us <= 0:
            raise ValueError(f"logger interval must be positive, got {interval_us} us")
        self.log_root = Path(log_root)
        self.mode = mode
        self.profile_name = profile if isinstance(profile, str) else "custom"
        self.params_provider = params_provider
        self.utc_epoch_s = utc_epoch_s
        self._utc_us = utc_us
        self.sd_write_rate_bytes_s = sd_write_rate_bytes_s
        self.buffer_bytes = buffer_bytes
        self.interval_us_setting = interval_us
        self.sync_interval_us = sync_interval_us
        self.info = dict(DEFAULT_INFO)
        if info:
            self.info.update(info)
        orb = platform.orb
        reg = orb.registry
        #: profile rows whose topic exists in this tree (others skipped quietly)
        self.topics: list[LoggedTopic] = []
        self.skipped: list[str] = []
        for row in get_profile(profile):
            if row.name not in reg.topics:
                self.skipped.append(row.name)
                continue
            try:
                formats_for(row.name, reg.topic(row.name), reg)
            except UlogError as exc:   # e.g. no leading timestamp: say so, log the rest
                platform.warn("logger", f"not logging {row.name}: {exc}")
                self.skipped.append(row.name)
                continue
            self.topics.append(row)
        self._subs: list[_TopicSub] = []
        self._known: set[tuple[str, int]] = set()
        self._seen_advertisements = -1
        for row in self.topics:
            self._subscribe(row, 0)
        self._log_sub = Subscription(orb, "log_message") if "log_message" in reg.topics else None
        self._param_sub = (Subscription(orb, "parameter_update")
                           if "parameter_update" in reg.topics else None)
        self._status_sub = None
        self._is_armed = is_armed
        if mode == "arm" and is_armed is None:
            st = reg.topics.get("vehicle_status")
            if st is None or "arming_state" not in [f.name for f in st.fields]:
                raise ValueError("logger mode 'arm' needs is_armed() or a vehicle_status topic "
                                 "with arming_state")
            self._status_sub = Subscription(orb, "vehicle_status")
        self._armed = False
        # per-file state
        self.writer: UlogWriter | None = None
        self.buffer: SdWriteBuffer | None = None
        self.current_path: Path | None = None
        self.log_files: list[Path] = []
        self._params: dict[str, int | float] = {}
        self._start_us = 0
        self._next_sync_us = 0
        self._in_dropout = False
        self._dropout_start_us = 0
        self.dropouts = 0
        self.dropout_total_ms = 0
        self.dropout_max_ms = 0
        self.dropped_messages = 0
        self.data_messages = 0
        self.last_file_bytes = 0
        self.running = False

    # -- module lifecycle -------------------------------------------------------------------

    def start(self) -> None:
        """Start polling; in mode "boot" the file opens now."""
        self.running = True
        if self.mode == "boot":
            self.start_log()
        self.schedule_on_interval(self.interval_us_setting)

    def stop(self) -> None:
        """Stop polling and close the current file (all buffered data is written)."""
        self.schedule_clear()
        self.running = False
        if self.writer is not None:
            self.stop_log()

    @property
    def logging(self) -> bool:
        return self.writer is not None

    # -- files --------------------------------------------------------------------------------

    def utc_us(self) -> int:
        if self._utc_us is not None:
            return self._utc_us()
        return self.utc_epoch_s * 1_000_000 + self.platform.hrt.absolute_time()

    def _new_path(self) -> Path:
        base = log_path_for(self.log_root, self.utc_us())
        path, n = base, 1
        while path.exists() or path in self.log_files:
            path = base.with_name(f"{base.stem}_{n}{base.suffix}")
            n += 1
        return path

    def start_log(self) -> Path:
        """Open a new file and write its definitions section."""
        if self.writer is not None:
            self.stop_log()
        now = self.platform.hrt.absolute_time()
        path = self._new_path()
        path.parent.mkdir(parents=True, exist_ok=True)
        self.buffer = SdWriteBuffer(open(path, "wb"), self.buffer_bytes,  # noqa: SIM115
                                    self.sd_write_rate_bytes_s, now)
        w = self.writer = UlogWriter(self.buffer, now)
        self.current_path = path
        self.log_files.append(path)
        self._start_us = now
        self._next_sync_us = now + self.sync_interval_us
        self._in_dropout = False
        self.dropouts = self.dropout_total_ms = self.dropout_max_ms = 0
        self.dropped_messages = self.data_messages = 0
        reg = self.platform.orb.registry
        for row in self.topics:
            w.write_topic_formats(row.name, reg.topic(row.name), reg)
        for key, value in self.info.items():
            if isinstance(value, tuple):
                w.write_info(key, value[0], value[1])
            else:
                w.write_info(key, value)
        self._params = dict(self.params_provider()) if self.params_provider else {}
        for name in sorted(self._params):
            w.write_parameter(name, self._params[name])
        self.buffer.flush()          # PX4 writes the header section blocking
        self.buffer.max_fill = 0
        if self._param_sub is not None:
            self._param_sub.copy()   # the values just written are current
        # PX4 writes the current state of every topic at the start of a file
        for ts in self._subs:
            ts.msg_id = None
            g = ts.sub.node.generation
            ts.sub.last_gen = g - 1 if g > 0 else 0
            if isinstance(ts.sub, SubscriptionInterval):
                ts.sub.last_update_us = -(1 << 62)
        if self._log_sub is not None:
            self._log_sub.copy()     # messages from before this file are not in it
        self.platform.info("logger", f"Opened full log file: {path.name}")
        return path

    def stop_log(self) -> None:
        if self.writer is None:
            return
        self._poll()                 # what was published up to now belongs in this file
        assert self.buffer is not None
        if self._in_dropout:         # the file ends inside a gap: record it (written blocking)
            self._end_dropout(self.platform.hrt.absolute_time())
        self.buffer.close()
        self.last_file_bytes = self.writer.bytes_written
        self.writer = None
        self.platform.info("logger", f"closed log file: {self.current_path.name}"
                           if self.current_path else "closed log file")

    # -- work item ----------------------------------------------------------------------------

    def _subscribe(self, row: LoggedTopic, instance: int) -> _TopicSub:
        orb = self.platform.orb
        iv = row.interval_us
        sub = (SubscriptionInterval(orb, row.name, iv, instance) if iv
               else Subscription(orb, row.name, instance))
        ts = _TopicSub(row.name, instance, sub, iv == 0)
        self._subs.append(ts)
        self._known.add((row.name, instance))
        return ts

    def _discover_instances(self) -> None:
        orb = self.platform.orb
        if orb.advertisements == self._seen_advertisements:
            return  # nothing new advertised since the last look
        self._seen_advertisements = orb.advertisements
        for row in self.topics:
            for i in range(1, ORB_MULTI_MAX_INSTANCES):
                if (row.name, i) not in self._known and orb.exists(row.name, i):
                    self._subscribe(row, i)

    def _armed_now(self) -> bool:
        if self._is_armed is not None:
            return bool(self._is_armed())
        assert self._status_sub is not None
        msg = self._status_sub.update()
        if msg is not None:
            self._armed = msg.arming_state == ARMING_STATE_ARMED
        return self._armed

    def run(self) -> None:
        if self.mode == "arm":
            armed = self._armed_now()
            if armed and self.writer is None:
                self.start_log()
            elif not armed and self.writer is not None:
                self.stop_log()
        if self.writer is None:
            if self._log_sub is not None:
                self._log_sub.copy()
            return
        self._poll()

    def _poll(self) -> None:
        """One logging pass: drain the card, then log every update due since the last pass."""
        now = self.platform.hrt.absolute_time()
        assert self.buffer is not None
        self.buffer.drain(now)
        self._discover_instances()
        self._poll_params()
        for ts in self._subs:
            sub = ts.sub
            if sub.node.generation == sub.last_gen:
                continue  # nothing new on this topic: no update() call, no time read
            if ts.every:
                for msg in sub.update_all():
                    self._write_sample(ts, msg, now)
            else:
                msg = sub.update()
                if msg is not None:
                    self._write_sample(ts, msg, now)
        self._poll_log_messages()
        if now >= self._next_sync_us:
            self._next_sync_us += self.sync_interval_us
            if self._next_sync_us <= now:
                self._next_sync_us = now + self.sync_interval_us
            self._write_droppable(UlogWriter.sync_message(), now)

    def _write_sample(self, ts: _TopicSub, msg: Any, now: int) -> None:
        w = self.writer
        assert w is not None
        if ts.msg_id is None:
            ts.msg_id = w.add_subscription(ts.topic, ts.instance)
        if self._write_droppable(UlogWriter.data_message(ts.msg_id, msg.pack()), now):
            self.data_messages += 1

    def _write_droppable(self, encoded: bytes, now: int) -> bool:
        buf, w = self.buffer, self.writer
        assert buf is not None and w is not None
        if self._in_dropout:
            o = UlogWriter.dropout_message(0)
            if not buf.fits(len(o) + len(encoded)):
                self.dropped_messages += 1
                return False
            self._end_dropout(now)
        elif not buf.fits(len(encoded)):
            self._in_dropout = True
            self._dropout_start_us = now
            self.dropped_messages += 1
            return False
        w.write_raw_message(encoded)
        return True

    def _end_dropout(self, now: int) -> None:
        assert self.writer is not None
        ms = min(0xFFFF, max(1, (now - self._dropout_start_us + 500) // 1000))
        self.writer.write_dropout(ms)
        self._in_dropout = False
        self.dropouts += 1
        self.dropout_total_ms += ms
        self.dropout_max_ms = max(self.dropout_max_ms, ms)

    def _poll_params(self) -> None:
        if self._param_sub is None or self.params_provider is None:
            return
        if self._param_sub.update() is None:
            return
        self._param_sub.copy()
        new = self.params_provider()
        w = self.writer
        assert w is not None
        for name in sorted(new):
            value = new[name]
            old = self._params.get(name)
            if old is None or old != value or type(old) is not type(value):
                w.write_parameter(name, value)
        self._params = dict(new)

    def _poll_log_messages(self) -> None:
        sub = self._log_sub
        w = self.writer
        if sub is None or w is None:
            return
        while True:
            msg = sub.update()
            if msg is None:
                break
            w.write_logged_string(min(max(int(msg.severity), 0), 7), msg.timestamp, msg.text)

    # -- shell --------------------------------------------------------------------------------

    def status(self) -> str:
        state = "running" if self.running else "stopped"
        lines = [(f"logger: {state}, mode {self.mode}, profile {self.profile_name}, "
                  f"{len(self.topics)} topics ({len(self._subs)} subscriptions)")]
        if self.skipped:
            lines.append(f"  not in this build: {len(self.skipped)} topics")
        if self.writer is None or self.buffer is None:
            lines.append("  not logging" + (" (waiting for arming)" if self.mode == "arm"
                                            and self.running else ""))
            if self.log_files:
                lines.append(f"  last file: {self.log_files[-1]} ({self.last_file_bytes} B)")
                lines.append(self._dropout_line())
            return "\n".join(lines)
        now = self.platform.hrt.absolute_time()
        dur_s = max(now - self._start_us, 1) / 1e6
        size = self.writer.bytes_written
        lines.append(f"  file: {self.current_path}")
        lines.append(f"  wrote {size} B ({size / 1024:.1f} KiB) in {dur_s:.2f} s, "
                     f"avg {size / 1024 / dur_s:.2f} KiB/s; on card {self.buffer.written} B")
        lines.append(f"  buffer: {len(self.buffer.pending)} / {self.buffer.capacity} B "
                     f"(max {self.buffer.max_fill}), SD rate {self.sd_write_rate_bytes_s} B/s")
        lines.append(self._dropout_line())
        return "\n".join(lines)

    def _dropout_line(self) -> str:
        return (f"  dropouts: {self.dropouts} (total {self.dropout_total_ms / 1000:.3f} s, "
                f"max {self.dropout_max_ms / 1000:.3f} s), "
                f"{self.dropped_messages} messages dropped")
