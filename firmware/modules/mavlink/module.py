"""``mavlink``: the shell module that owns every MAVLink link of the FMU.

PX4 runs one ``mavlink`` instance per link and ``mavlink start`` may be called several times;
here one module object holds the instances (``MULTI_INSTANCE``): the registry starts the module
with the first link, later ``mavlink start`` calls add links through :meth:`start_instance`.

Command line (PX4's)::

    mavlink start -d /dev/ttyS1 [-b 57600] [-m normal|onboard|config|minimal] [-r BYTES_PER_S]
    mavlink start -u LOCAL_PORT [-o REMOTE_PORT] [-m MODE] [-r BYTES_PER_S]
    mavlink stop-all | status [streams] | stream (-d DEV | -u PORT) -s MSG -r RATE_HZ
    mavlink signing [--key HEX64 | off]      (no argument: show the state)

Signing follows PX4: the 32-byte key lives on the SD card in ``mavlink/mavlink-signing-key.bin``
(key then 8-byte timestamp), ``MAV_SIGN_CFG`` (0 off, 1 on except USB, 2 always) enables it;
with a key and signing enabled, every outgoing message is signed and unsigned incoming messages
(other than RADIO_STATUS) are refused. A GCS can set the key with SETUP_SIGNING.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from firmware.modules.mavlink.instance import LOOP_INTERVAL_US, MavlinkInstance
from firmware.modules.mavlink.streams import DEFAULT_RATES
from firmware.modules.mavlink.transport import TransportError, UartTransport, UdpTransport
from firmware.platform.module import ModuleBase, ModuleError, UsageError
from firmware.platform.params import ParamDef

if TYPE_CHECKING:
    from firmware.system import System

__all__ = ["SIGNING_KEY_PATH", "MavlinkModule"]

_G = "MAVLink"
#: where PX4 keeps the signing key, relative to the SD card
SIGNING_KEY_PATH = "mavlink/mavlink-signing-key.bin"
MAX_INSTANCES = 4
#: default data rate of a serial link: what PX4 uses when -r is not given (baud / 20 B/s)
_UDP_DEFAULT_RATE = 100_000


class _Config:
    __slots__ = ("baud", "device", "mode", "rate", "remote_port", "udp_port")

    def __init__(self) -> None:
        self.device: str | None = None
        self.baud = 57_600
        self.udp_port: int | None = None
        self.remote_port = 14550
        self.mode = "normal"
        self.rate = 0


def _int(opt: str, text: str) -> int:
    try:
        return int(text, 0)
    except ValueError:
        raise UsageError(f"option {opt} needs a number, got {text!r}") from None


def parse_start(args: Sequence[str]) -> _Config:
    cfg = _Config()
    it = iter(args)
    for a in it:
        if a in ("-d", "-b", "-u", "-o", "-m", "-r", "-t", "-p"):
            try:
                v = next(it)
            except StopIteration:
                raise UsageError(f"option {a} needs a value") from None
            if a == "-d":
                cfg.device = v
            elif a == "-b":
                cfg.baud = _int(a, v)
            elif a == "-u":
                cfg.udp_port = _int(a, v)
            elif a == "-o":
                cfg.remote_port = _int(a, v)
            elif a == "-m":
                if v not in DEFAULT_RATES:
                    raise UsageError(f"unknown mode {v!r} (modes: {', '.join(DEFAULT_RATES)})")
                cfg.mode = v
            elif a == "-r":
                cfg.rate = _int(a, v)
        elif a in ("-x", "-f", "-w", "-s", "-z"):
            continue  # PX4 options with no meaning here (FTP, forwarding, wait, ...)
        else:
            raise UsageError(f"unknown option {a!r}")
    if (cfg.device is None) == (cfg.udp_port is None):
        raise UsageError("give exactly one of -d DEVICE and -u PORT")
    if cfg.rate <= 0:
        cfg.rate = cfg.baud // 20 if cfg.device else _UDP_DEFAULT_RATE
    return cfg


class MavlinkModule(ModuleBase):
    NAME = "mavlink"
    DESCRIPTION = "MAVLink links: telemetry streams, parameters, commands, missions, shell, logs"
    USAGE = (
        "start -d DEV [-b BAUD] [-m MODE] [-r RATE]  a serial link (MODE normal|onboard|config)",
        "start -u PORT [-o REMOTE] [-m MODE] [-r RATE]  a UDP link on the board's network port",
        "stop-all                   stop every link",
        "status [streams]           links, counters, streams",
        "stream (-d DEV|-u PORT) -s MSG -r HZ  set a stream's rate (0 stops it)",
        "signing [off|--key HEX64]  MAVLink 2 signing: show, remove or set the key",
    )
    PARAMS = (
        ParamDef("MAV_SYS_ID", "INT32", 1, min=1, max=250, group=_G, short="MAVLink system ID",
                 reboot_required=True),
        ParamDef("MAV_COMP_ID", "INT32", 1, min=1, max=250, group=_G,
                 short="MAVLink component ID", reboot_required=True),
        ParamDef("MAV_TYPE", "INT32", 2, min=0, max=22, group=_G, short="MAVLink airframe type",
                 values={1: "Fixed wing", 2: "Quadrotor", 13: "Hexarotor", 14: "Octorotor"}),
        ParamDef("MAV_SIGN_CFG", "INT32", 1, min=0, max=2, group=_G,
                 short="MAVLink protocol signing",
                 long="Signing is active once a key is set (SETUP_SIGNING or "
                      "'mavlink signing --key'); unsigned messages are then refused.",
                 values={0: "Disabled", 1: "Enabled except on USB", 2: "Always"}),
    )
    #: the registry lets a running module start more instances (``mavlink start`` again)
    MULTI_INSTANCE = True

    def __init__(self, system: System, args: Sequence[str] = ()) -> None:
        super().__init__(system, args)
        self.instances: list[MavlinkInstance] = []
        self.signing_key: bytes | None = None
        #: UTC minus the boot clock set by a GCS's SYSTEM_TIME (0: not set), shared by the
        #: links as PX4's CLOCK_REALTIME is (see :mod:`firmware.modules.mavlink.systime`)
        self.gcs_utc_offset_us = 0
        self._first = parse_start(args)

    @classmethod
    def instantiate(cls, system: System, args: Sequence[str]) -> MavlinkModule:
        if system.params is None or "MAV_SYS_ID" not in system.params:
            raise ModuleError("no MAV_* parameters on this system (params not loaded)")
        return cls(system, args)

    # -- instances ------------------------------------------------------------------------------

    def _start(self) -> None:
        self.signing_key = self._load_key()
        self._add(self._first)

    def start_instance(self, args: Sequence[str]) -> int:
        """Another ``mavlink start``: one more link; prints why not and returns 1 on errors."""
        try:
            self._add(parse_start(args))
        except UsageError as exc:
            self.print(f"mavlink: {exc}")
            self.print_usage()
            return 1
        except ModuleError as exc:
            self.print(f"mavlink: {exc}")
            return 1
        return 0

    def _add(self, cfg: _Config) -> MavlinkInstance:
        if len(self.instances) >= MAX_INSTANCES:
            raise ModuleError(f"at most {MAX_INSTANCES} instances")
        hw = getattr(self.system, "hw", None)
        k = self.platform.kernel
        try:
            if cfg.device is not None:
                if any(getattr(i.transport, "device", None) == cfg.device for i in self.instances):
                    raise ModuleError(f"{cfg.device} already in use by a mavlink instance")
                uart = hw.uart_by_device(cfg.device) if hw is not None else None
                if uart is None:
                    raise ModuleError(f"no serial device {cfg.device} on this board")
                transport: Any = UartTransport(uart, cfg.device, cfg.baud)
                wq = f"wq:{cfg.device.rsplit('/', 1)[-1]}"
            else:
                assert cfg.udp_port is not None
                transport = UdpTransport(hw, k, cfg.udp_port, cfg.remote_port)
                wq = "wq:lp_default"
        except TransportError as exc:
            raise ModuleError(str(exc)) from None
        index = next(i for i in range(MAX_INSTANCES)
                     if all(inst.index != i for inst in self.instances))
        inst = MavlinkInstance(self, index, transport, cfg.mode, cfg.rate, wq)
        self.add_work_item(inst)
        self.instances.append(inst)
        inst.schedule_on_interval(LOOP_INTERVAL_US, delay_us=1 + index * 1000)
        self.info(f"mode: {cfg.mode}, data rate: {cfg.rate} B/s on {transport.describe()}")
        return inst

    def _stop(self) -> None:
        for inst in self.instances:
            inst.stop()
        self.instances.clear()

    def find(self, device: str | None, udp_port: int | None) -> MavlinkInstance | None:
        for inst in self.instances:
            t = inst.transport
            if device is not None and getattr(t, "device", None) == device:
                return inst
            if udp_port is not None and getattr(t, "local_port", None) == udp_port:
                return inst
        return None

    # -- signing ----------------------------------------------------------------------------

    def _key_path(self) -> Path | None:
        sd = self.system.sd_root
        return None if sd is None else Path(sd) / SIGNING_KEY_PATH

    def _load_key(self) -> bytes | None:
        path = self._key_path()
        if path is None or not path.is_file():
            return None
        data = path.read_bytes()
        if len(data) < 32 or data[:32] == b"\0" * 32:
            return None
        return data[:32]

    def signing_active(self) -> bool:
        return self.signing_key is not None and int(self.param("MAV_SIGN_CFG")) != 0

    def set_signing_key(self, key: bytes | None, timestamp: int = 0) -> None:
        """Install (or with None remove) the key on every link and persist it on the SD card."""
        if key is not None and (len(key) != 32 or key == b"\0" * 32):
            key = None  # PX4: an all-zero key disables signing
        self.signing_key = key
        path = self._key_path()
        if path is not None:
            try:
                if key is None:
                    path.unlink(missing_ok=True)
                else:
                    path.parent.mkdir(parents=True, exist_ok=True)
                    path.write_bytes(key + struct.pack("<Q", timestamp))
            except OSError as exc:
                self.warn(f"signing key not saved: {exc}")
        for inst in self.instances:
            inst.apply_signing()
        self.info("signing " + ("enabled" if self.signing_active() else "disabled"))

    # -- shell ------------------------------------------------------------------------------

    def custom_command(self, args: list[str]) -> int:
        verb = args[0]
        if verb == "stop-all":
            self.system.modules.stop(self.name)
            return 0
        if verb == "stream":
            return self._cmd_stream(args[1:])
        if verb == "signing":
            return self._cmd_signing(args[1:])
        return super().custom_command(args)

    def _cmd_stream(self, args: list[str]) -> int:
        device = port = msg = rate = None
        it = iter(args)
        for a in it:
            v = next(it, None)
            if v is None:
                raise UsageError(f"option {a} needs a value")
            if a == "-d":
                device = v
            elif a == "-u":
                port = _int(a, v)
            elif a == "-s":
                msg = v
            elif a == "-r":
                try:
                    rate = float(v)
                except ValueError:
                    raise UsageError(f"rate {v!r} is not a number") from None
            else:
                raise UsageError(f"unknown option {a!r}")
        if msg is None or rate is None:
            raise UsageError("stream needs -s MSG and -r RATE")
        found = self.find(device, port) if device or port else None
        targets = [found] if found is not None else [] if device or port else \
            list(self.instances)
        if not targets:
            self.print(f"mavlink: no instance on {device or port}")
            return 1
        for inst in targets:
            if not inst.set_stream_rate(msg, rate):
                self.print(f"mavlink: unknown stream {msg}")
                return 1
        return 0

    def _cmd_signing(self, args: list[str]) -> int:
        if not args:
            state = "active" if self.signing_active() else \
                "key set, MAV_SIGN_CFG 0" if self.signing_key else "no key"
            self.print(f"mavlink signing: {state}")
            return 0
        if args[0] == "off":
            self.set_signing_key(None)
            return 0
        if args[0] == "--key" and len(args) == 2:
            try:
                key = bytes.fromhex(args[1])
            except ValueError:
                raise UsageError("the key must be 64 hex digits") from None
            if len(key) != 32:
                raise UsageError("the key must be 64 hex digits (32 bytes)")
            self.set_signing_key(key)
            return 0
        raise UsageError("signing [off|--key HEX64]")

    def print_status(self) -> None:
        self.print(f"{self.name}: running, {len(self.instances)} instance(s)")
        for inst in self.instances:
            for line in inst.status_lines():
                self.print(line)
