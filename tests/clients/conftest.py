"""``hil fly`` as a subprocess for tests with real MAVLink clients (MAVSDK, pymavlink).

Each test module gets one emulator (module-scoped fixture), started exactly as a user starts
it (``.venv/bin/hil fly --speed S --out TMPDIR --seed 1``), waited for until it prints its
"Ctrl-C to stop" line, and stopped at teardown: SIGINT (the Ctrl-C the banner asks for), then
SIGKILL of its whole process group (its board processes included), so no process is left.

The emulator is paced to the wall clock at ``--speed`` (``HIL_CLIENTS_SPEED``, default 2.5: the
clients see a vehicle that lives 2.5 virtual seconds per wall second, and the suite spends less
time waiting for flights: the client tests' paced pass took 108 s at 2.5 against 127 s at 1.5
on two cores; real clients must cope with a vehicle whose clock is not theirs anyway, and the
heartbeat keepalive of hil/mavlink_bridge.py covers a run that falls behind); on a loaded or
slower machine it runs as fast as it can, so every wait here is in wall-clock seconds and
generous (scaled by ``HIL_CLIENTS_TIMEOUT_SCALE``, default 1).

Known emulator gaps that a test works around are reported with :func:`gap`: by default the
test goes on (or ends as xfail with the exact gap as reason); with ``HIL_CLIENTS_STRICT=1`` a
gap fails the test. See docs/clients.md ("Known gaps").
"""

from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from hil.shell_client import run_command, runtime_dir
from tests.helpers import ctrl_c_reaches_child

#: UDP ports ``hil fly`` binds (host side of the GCS and API links) and the client ports
VEHICLE_GCS_SOCKET = 18570   # vehicle's socket of the GCS link: send here to reach the FMU
VEHICLE_API_SOCKET = 14580   # vehicle's socket of the API link
GCS_PORT = 14550             # the vehicle sends GCS traffic here (QGC, MAVProxy, mavutil)
API_PORT = 14540             # the vehicle sends API traffic here (MAVSDK)

SPEED = float(os.environ.get("HIL_CLIENTS_SPEED", "2.5"))
TIMEOUT_SCALE = float(os.environ.get("HIL_CLIENTS_TIMEOUT_SCALE", "1.0"))
STRICT = os.environ.get("HIL_CLIENTS_STRICT", "") not in ("", "0")

HOME_LAT, HOME_LON = 47.397742, 8.545594

ROOT = Path(__file__).resolve().parents[2]
HIL_EXE = Path(sys.executable).with_name("hil")

#: ``hil fly`` with the FRAM kept (used only when ``hil fly`` has no flag for it): the same
#: ``hil.fly.main``, with ``SystemConfig.fresh_fram`` forced off.
_KEEP_FRAM_LAUNCHER = """
import dataclasses, sys
import hil.fly
_build = hil.fly.build_system
hil.fly.build_system = lambda cfg: _build(dataclasses.replace(cfg, fresh_fram=False))
from hil.cli import main
sys.exit(main(["fly", *sys.argv[1:]]))
"""


def wall(seconds: float) -> float:
    """A wall-clock timeout, scaled for slow machines."""
    return seconds * TIMEOUT_SCALE


def gap(where: str, what: str) -> None:
    """Record a known emulator gap: fail under HIL_CLIENTS_STRICT, else print it and go on."""
    text = f"EMULATOR GAP [{where}]: {what}"
    print(text, file=sys.stderr, flush=True)
    if STRICT:
        pytest.fail(text)


def udp_port_free(port: int) -> bool:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        s.bind(("127.0.0.1", port))
        return True
    except OSError:
        return False
    finally:
        s.close()


def free_tcp_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def hil_fly_has_flag(flag: str) -> bool:
    out = subprocess.run([str(HIL_EXE), "fly", "--help"], capture_output=True, text=True,
                         timeout=60, check=False).stdout
    return flag in out


class HilFly:
    """One ``hil fly`` process."""

    READY = "Ctrl-C to stop"

    def __init__(self, out_dir: Path, speed: float = SPEED, seed: int = 1) -> None:
        self.out_dir = Path(out_dir)
        self.speed = speed
        self.seed = seed
        self.proc: subprocess.Popen | None = None
        self.lines: list[str] = []
        self.console_port: int | None = None
        self._reader: threading.Thread | None = None
        self.starts = 0

    # -- life cycle ---------------------------------------------------------------------------

    def start(self, keep_fram: bool = False, timeout_s: float = 180.0,
              client_ports_free: bool = True) -> None:
        ports = (VEHICLE_GCS_SOCKET, VEHICLE_API_SOCKET) + \
            ((GCS_PORT, API_PORT) if client_ports_free else ())
        busy = [p for p in ports if not udp_port_free(p)]
        if busy:
            pytest.fail(f"UDP port(s) {busy} on 127.0.0.1 are in use: another 'hil fly', "
                        f"QGroundControl, MAVProxy or MAVSDK is running; stop it first")
        args = ["--speed", f"{self.speed:g}", "--out", str(self.out_dir), "--seed",
                str(self.seed)]
        if not keep_fram:
            cmd = [str(HIL_EXE), "fly", *args]
        elif hil_fly_has_flag("--keep-fram"):
            cmd = [str(HIL_EXE), "fly", "--keep-fram", *args]
        else:
            gap("hil/cli.py build_parser 'fly', hil/fly.py main",
                "'hil fly' has no flag to keep the FRAM (SystemConfig.fresh_fram is always "
                "True, so every start erases fram.bin and the parameters); restarting through "
                "hil.fly.main with fresh_fram forced off instead")
            cmd = [sys.executable, "-c", _KEEP_FRAM_LAUNCHER, *args]
        self.lines = []
        self.console_port = None
        self.out_dir.mkdir(parents=True, exist_ok=True)
        self.proc = subprocess.Popen(cmd, cwd=str(ROOT), stdin=subprocess.DEVNULL,
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                     text=True, bufsize=1, start_new_session=True,
                                     preexec_fn=ctrl_c_reaches_child)  # noqa: PLW1509 (before the reader thread)
        self.starts += 1
        ready = threading.Event()

        def read(proc: subprocess.Popen = self.proc) -> None:
            assert proc.stdout is not None
            for line in proc.stdout:
                line = line.rstrip("\n")
                self.lines.append(line)
                m = re.search(r"tcp 127\.0\.0\.1:(\d+)", line)
                if m and self.console_port is None:
                    self.console_port = int(m.group(1))
                if self.READY in line:
                    ready.set()
            ready.set()

        self._reader = threading.Thread(target=read, daemon=True, name="hil-fly-stdout")
        self._reader.start()
        if not ready.wait(wall(timeout_s)) or self.proc.poll() is not None:
            out = self.output()
            self.stop()
            pytest.fail(f"'hil fly' did not print {self.READY!r} within {wall(timeout_s):.0f} s "
                        f"(exit code {self.proc.returncode}); its output:\n{out}")
        if self.console_port is None:  # the banner changed: the instance file has it
            info = runtime_dir() / f"{self.proc.pid}.json"
            import json
            self.console_port = int(json.loads(info.read_text())["console_tcp"])
        self._wait_console(timeout_s)

    def _wait_console(self, timeout_s: float) -> None:
        """The banner comes before rcS has finished: a line typed too early is lost, so ask
        until nsh answers."""
        deadline = time.monotonic() + wall(timeout_s)
        while True:
            try:
                run_command(self.console_port, "ver all", 5.0)
                return
            except (OSError, TimeoutError):
                if time.monotonic() > deadline or not self.alive():
                    out = self.output()
                    self.stop()
                    pytest.fail(f"the FMU console (tcp {self.console_port}) never answered "
                                f"within {wall(timeout_s):.0f} s; hil fly output:\n{out}")

    def stop(self, timeout_s: float = 30.0) -> int | None:
        """SIGINT, then SIGKILL of the process group; returns the exit code."""
        proc = self.proc
        if proc is None:
            return None
        if proc.poll() is None:
            try:
                proc.send_signal(signal.SIGINT)
                proc.wait(wall(timeout_s))
            except subprocess.TimeoutExpired:
                pass
        try:
            os.killpg(proc.pid, signal.SIGKILL)  # the boards' processes too (own session)
        except (ProcessLookupError, PermissionError):
            pass
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            pass
        if self._reader is not None:
            self._reader.join(5)
        try:
            (runtime_dir() / f"{proc.pid}.json").unlink()
        except FileNotFoundError:
            pass
        return proc.returncode

    def restart(self, keep_fram: bool) -> None:
        """Stop and start again with the same out dir (the test's clients keep their ports)."""
        self.stop()
        self.start(keep_fram=keep_fram, client_ports_free=False)

    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def output(self) -> str:
        return "\n".join(self.lines[-60:])

    # -- console ------------------------------------------------------------------------------

    def shell(self, command: str, timeout_s: float = 60.0) -> str:
        """Run one nsh command on the FMU console (as ``hil shell -c``)."""
        assert self.console_port is not None, "emulator not started"
        try:
            return run_command(self.console_port, command, wall(timeout_s))
        except (OSError, TimeoutError) as exc:
            raise AssertionError(
                f"the FMU console gave no prompt for {command!r} within {wall(timeout_s):.0f} s "
                f"({exc}): the FMU board may have died (hil fly prints the reason only when it "
                f"exits).\nhil fly output:\n{self.output()}") from None

    def param(self, name: str) -> float:
        out = self.shell(f"param show {name}")
        m = re.search(rf"\b{re.escape(name)}\s*\[\d+\]\s*:\s*(\S+)", out)
        assert m, f"'param show {name}' printed no value:\n{out}"
        return float(m.group(1))

    def ensure_api_link(self) -> bool:
        """Make the FMU's API link (UDP 14540) reach ``hil fly``'s 14580 socket; returns True
        if a workaround was needed (see docs/clients.md, gap 1)."""
        status = self.shell("mavlink status")
        if re.search(rf"udp local port {VEHICLE_API_SOCKET}\b", status):
            return False
        gap("firmware/romfs/init.d/rcS line 'mavlink start -u 18580 -o 14540 -m onboard' vs "
            "hil/mavlink_bridge.py DEFAULT_ENDPOINTS (14580, 14580, 14540)",
            "the API link runs on FMU port 18580 but the host bridge carries FMU port 14580, so "
            "MavlinkUdpBridge.input drops every datagram of the onboard link and nothing "
            "reaches UDP 14540 (MAVSDK sees no vehicle); starting "
            "'mavlink start -u 14580 -o 14540 -m onboard' on the console instead")
        self.shell(f"mavlink start -u {VEHICLE_API_SOCKET} -o {API_PORT} -m onboard")
        status = self.shell("mavlink status")
        assert re.search(rf"udp local port {VEHICLE_API_SOCKET}\b", status), status
        return True


def mc_rate_runs(text: str) -> int:
    m = re.search(r"mc_rate_control[^\n]*?:\s*(\d+) runs", text)
    assert m, f"no run count in 'mc_rate_control status':\n{text}"
    return int(m.group(1))


@pytest.fixture(scope="module")
def hil_fly(tmp_path_factory: pytest.TempPathFactory):
    assert HIL_EXE.exists(), f"{HIL_EXE} not found: install the package (pip install -e .)"
    fly = HilFly(tmp_path_factory.mktemp("hil_fly"))
    fly.start()
    try:
        yield fly
    finally:
        code = fly.stop()
        tail = "\n".join(line for line in fly.lines if "died" in line)
        if tail:
            print(f"hil fly (exit {code}): {tail}", file=sys.stderr)


def wait_until(pred: Any, timeout_s: float, what: str, every_s: float = 0.2) -> Any:
    deadline = time.monotonic() + wall(timeout_s)
    while time.monotonic() < deadline:
        value = pred()
        if value:
            return value
        time.sleep(every_s)
    raise AssertionError(f"timed out after {wall(timeout_s):.0f} s waiting for {what}")
