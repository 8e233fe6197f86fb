"""``hil fly``: the emulator paced to the wall clock, for ground stations, scripts and people.

Both boards and the world run in lockstep, paced at ``--speed`` times real time (1.0 by default).
MAVLink is reachable on 127.0.0.1 the way PX4 SITL users expect:

* QGroundControl and MAVProxy: the vehicle sends to UDP 14550 (QGC finds it by itself;
  ``mavproxy.py --master=udpin:127.0.0.1:14550``),
* MAVSDK and other API clients: the vehicle sends to UDP 14540 (``udp://:14540``),
* TELEM1 and TELEM2 (the radio connectors, MAVLink on TELEM1 at 57600) on host
  pseudo-terminals, as a radio modem plugged into a laptop would appear,

and the FMU console (nsh) is on a host pseudo-terminal and a TCP port, which ``hil shell``
finds by itself. Tools and hardware attach as well (docs/attaching.md): CAN1 is a python-can bus
(``can.Bus(interface="hil", channel="CAN1")``, ``python -m can.logger -i hil -c CAN1``, a
``dronecan`` node), TELEM1/TELEM2 are pyserial URLs (``hil://TELEM1``), ``--can CAN1=<bus>``
binds CAN1 to a real or virtual python-can bus and ``--uart gps=<URL>`` a real device or a
``socket://``/``rfc2217://`` endpoint to an emulated UART; the endpoints are printed at start
and announced for discovery. The safety switch is pressed for the user unless
``--keep-safety`` is given, since a ground station cannot press it (four seconds after power on,
once the FMU reports ready to arm: the IO ignores the button before).

The GPS reports the host's UTC at power on (read here, at the edge; the boards only get it as
configuration), so each run's logs get distinct names (``YYYY-MM-DD/HH_MM_SS.ulg``) as on a real
vehicle; ``--fixed-utc`` keeps the fixed epoch of ``hil run`` and the tests.
"""

from __future__ import annotations

import signal
import sys
import time
from typing import Any

from hil.can_interface_host import CanHost
from hil.shell_client import announce, withdraw
from hil.system import SystemConfig, build_system

__all__ = ["main"]

NS_PER_S = 1_000_000_000


def honour_sigint() -> None:
    """Make SIGINT raise KeyboardInterrupt even if this process was started with it ignored.

    A shell starts background jobs (``hil fly &`` in a script) with SIGINT set to SIG_IGN, the
    disposition is inherited, and Python then leaves it ignored instead of installing its
    KeyboardInterrupt handler (Python docs, ``signal``: "SIGINT is translated into a
    KeyboardInterrupt exception if the parent process has not changed it"). PX4 SITL and
    daemon-like tools stop on ``kill -INT``; so do ``hil fly`` and ``hil run``: the handler is
    installed explicitly and the normal clean shutdown (boards stopped, no orphans) follows.
    Board processes ignore SIGINT themselves (hil.boardproc) and are stopped by their parent.
    """
    signal.signal(signal.SIGINT, signal.default_int_handler)


def _assignments(items: list[str], what: str) -> dict[str, str]:
    """``["CAN1=virtual:x"]`` -> ``{"CAN1": "virtual:x"}``; ValueError saying what is wrong."""
    out: dict[str, str] = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name or not value:
            raise ValueError(f"{what} expects NAME=VALUE, got {item!r}")
        out[name] = value
    return out


def _number(text: str) -> int | float:
    try:
        return int(text)
    except ValueError:
        return float(text)


def main(seed: int = 1, speed: float = 1.0, duration_s: float | None = None,
         out_dir: str = "out", airframe: int = 4011, keep_safety: bool = False,
         params: dict[str, Any] | None = None, quiet: bool = False,
         keep_fram: bool = False, fixed_utc: bool = False, can: list[str] | None = None,
         uart: list[str] | None = None, param: list[str] | None = None,
         can_escs: bool = False, companion: bool = False, ros: bool = False) -> int:
    if speed <= 0:
        print("hil fly: --speed must be positive", file=sys.stderr)
        return 2
    try:
        can_bind = {k.upper(): v for k, v in _assignments(can or [], "--can").items()}
        uart_bind = {k.lower(): v for k, v in _assignments(uart or [], "--uart").items()}
        extra = {k: _number(v) for k, v in _assignments(param or [], "--param").items()}
        from hil.bindings_can import parse_can_spec

        for bus, spec in can_bind.items():
            if bus not in ("CAN1", "CAN2"):
                raise ValueError(f"--can: no CAN bus {bus!r} on the FMU (CAN1, CAN2)")
            parse_can_spec(spec)
        from hil.bindings_uart import CONNECTORS

        for name in uart_bind:
            if name not in CONNECTORS:
                raise ValueError(f"--uart: no connector {name!r} (one of "
                                 f"{', '.join(CONNECTORS)})")
    except ValueError as exc:
        print(f"hil fly: {exc}", file=sys.stderr)
        return 2
    honour_sigint()
    cfg = SystemConfig(seed=seed, out_dir=out_dir, airframe=airframe, speed=speed,
                       console=True, udp_bridge=True, telem_pty=True, uart_tcp=True,
                       fresh_fram=not keep_fram,
                       gps_utc_start_ns=None if fixed_utc else time.time_ns(),
                       can_hosts=("CAN1",), can_tcp=True, can_bind=can_bind,
                       uart_bind=uart_bind, can_escs=can_escs, companion=companion,
                       ros=ros,
                       params={"EKF2_MAG_DECL": 2.6, **(params or {}), **extra})
    try:
        orch, dev = build_system(cfg)
    except (ValueError, OSError) as exc:  # a binding that cannot open, a bad name
        print(f"hil fly: {exc}", file=sys.stderr)
        return 2
    say = (lambda text: None) if quiet else (lambda text: print(text, flush=True))
    orch.log = lambda text: print(text, file=sys.stderr, flush=True)  # deaths, reboots
    stop = {"now": False}

    def on_term(_signum: int, _frame: Any) -> None:
        stop["now"] = True

    signal.signal(signal.SIGTERM, on_term)
    try:
        with orch:
            from hil.faults import Injector

            Injector(orch, dev).install()  # MAV_CMD_INJECT_FAILURE (SYS_FAILURE_EN 1)
            console = dev["console"]
            # (the console's line stays the first with "tcp 127.0.0.1:<port>": scripts and
            # tests/clients read the console port from it)
            cans = {d.bus: d for d in dev.values() if isinstance(d, CanHost)}
            uarts = {name.upper(): dev[name].tcp_port for name in ("telem1", "telem2")
                     if getattr(dev.get(name), "tcp_port", None)}
            uarts["CONSOLE"] = console.tcp_port
            comp_console = dev.get("companion_console")
            announce({"console_tcp": console.tcp_port, "console_pty": console.pty_name,
                      "companion_console_tcp": getattr(comp_console, "tcp_port", None),
                      "mavlink_udp": [14550, 14540], "speed": speed,
                      "can": {b: {"port": h.tcp_port, "bitrate": h.bitrate}
                              for b, h in cans.items()},
                      "uart": uarts})
            boards = "FMU + IO + companion" if comp_console is not None else "FMU + IO"
            say(f"hil fly: Pixhawk 1 ({boards}) with the JSBSim F450, {speed:g}x real time, "
                f"seed {seed}")
            say("  QGroundControl / MAVProxy: the vehicle sends to udp 127.0.0.1:14550 "
                "(mavproxy.py --master=udpin:127.0.0.1:14550)")
            say("  MAVSDK / API:               udp://:14540")
            for name in ("telem1", "telem2"):
                if name in dev and getattr(dev[name], "pty_name", None):
                    say(f"  {name.upper() + ' (57600):':<28}{dev[name].pty_name}   "
                        f"hil://{name.upper()} (pyserial; TCP port {dev[name].tcp_port})")
            for b, h in cans.items():
                say(f"  {b + ' (python-can):':<28}can.Bus(interface='hil', "
                    f"channel='{b}')   (TCP port {h.tcp_port}, {h.bitrate // 1000} kbit/s)")
            for name, spec in can_bind.items():
                say(f"  {name + ' bound to:':<28}{spec}")
            for name, binding in dev.get("uart_bindings", {}).items():
                say(f"  {name.upper() + ' bound to:':<28}{binding.url}")
            say(f"  console (nsh):              hil shell   (tcp 127.0.0.1:{console.tcp_port}, "
                f"pty {console.pty_name})")
            if comp_console is not None:
                say(f"  companion console (nsh):    hil shell --board companion   (tcp "
                    f"127.0.0.1:{comp_console.tcp_port}, pty {comp_console.pty_name}); "
                    f"TELEM2 is its cable")
            if dev.get("ros") is not None:
                say(f"  {'ROS 1:':<28}{dev['ros'].describe()}")
            say("  Ctrl-C to stop.")
            if not keep_safety:
                # The IO takes the button only once the FMU is ready to arm (~2 s after boot).
                dev["safety"].press(4 * NS_PER_S, hold_s=1.5)
            end = None if duration_s is None else int(duration_s * NS_PER_S)
            last_report = time.monotonic()
            while not stop["now"] and (end is None or orch.t_ns < end):
                orch.run(duration_ns=100_000_000)
                if time.monotonic() - last_report > 10 and not quiet:
                    last_report = time.monotonic()
                    tr = dev["world"].world.truth()
                    say(f"  t = {orch.t_ns / NS_PER_S:7.1f} s  height {tr.agl_m:6.2f} m  "
                        f"real-time factor {orch.rtf:.2f}")
            if orch.dead:
                say(f"hil fly: board(s) died: {', '.join(orch.dead)}")
                return 1
    except KeyboardInterrupt:
        say("hil fly: stopped")
        return 130
    finally:
        withdraw()
        for name in ("console", "companion_console", "ros", "udp", "telem1", "telem2", *sorted(
                n for n, d in dev.items() if isinstance(d, CanHost))):
            close = getattr(dev.get(name), "close", None)
            if close is not None:
                close()
        for binding in dev.get("uart_bindings", {}).values():
            close = getattr(binding, "close", None)
            if close is not None:
                close()
    return 0
