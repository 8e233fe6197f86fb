"""``hil shell``: attach to the nsh console of a running emulator.

A running ``hil`` announces itself in a small JSON file per process under the runtime folder
(``$XDG_RUNTIME_DIR/fmu-hil`` or ``/tmp/fmu-hil-<uid>``): its pid and the TCP port and
pseudo-terminal of the FMU console. ``hil shell`` picks the newest live one (or ``--port``),
connects, and either runs one command (``-c``), printing its output up to the next prompt, or
stays interactive until end of input.
"""

from __future__ import annotations

import json
import os
import selectors
import socket
import sys
import time
from pathlib import Path
from typing import Any

__all__ = ["runtime_dir", "announce", "withdraw", "discover", "run_command", "main"]

PROMPT = b"nsh> "


def runtime_dir() -> Path:
    base = os.environ.get("XDG_RUNTIME_DIR")
    path = Path(base) / "fmu-hil" if base else Path(f"/tmp/fmu-hil-{os.getuid()}")
    path.mkdir(parents=True, exist_ok=True)
    return path


def announce(info: dict[str, Any]) -> Path:
    """Write this process's instance file (removed by :func:`withdraw`)."""
    path = runtime_dir() / f"{os.getpid()}.json"
    path.write_text(json.dumps({"pid": os.getpid(), "started": time.time(), **info}))
    return path


def withdraw() -> None:
    try:
        (runtime_dir() / f"{os.getpid()}.json").unlink()
    except FileNotFoundError:
        pass


def pid_alive(pid: int) -> bool:
    """Whether a process with this pid exists (one of another user counts as alive)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def discover() -> dict[str, Any] | None:
    """The newest running instance that announced a console, or None."""
    best = None
    for f in runtime_dir().glob("*.json"):
        try:
            info = json.loads(f.read_text())
        except (OSError, ValueError):
            continue
        if not pid_alive(int(info.get("pid", 0))):
            f.unlink(missing_ok=True)  # a stale file from a killed run
            continue
        if info.get("console_tcp") and (best is None or info["started"] > best["started"]):
            best = info
    return best


def run_command(port: int, command: str, timeout_s: float = 30.0) -> str:
    """Send one line to the console on ``port`` and return what it printed before the next
    prompt (the echo of the line removed)."""
    with socket.create_connection(("127.0.0.1", port), timeout=timeout_s) as sock:
        sock.sendall(command.encode() + b"\r")
        buf = bytearray()
        deadline = time.monotonic() + timeout_s
        while PROMPT not in buf:
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError(f"no prompt from the console within {timeout_s} s")
            sock.settimeout(left)
            chunk = sock.recv(4096)
            if not chunk:
                break
            buf += chunk
    text = bytes(buf).split(PROMPT, 1)[0].decode("utf-8", "replace")
    echo = command + "\r\n"
    if text.startswith(echo):
        text = text[len(echo):]
    return text.replace("\r\n", "\n")


def main(port: int | None = None, command: str | None = None, timeout_s: float = 30.0,
         board: str = "FMU") -> int:
    if port is None:
        info = discover()
        if info is None:
            print("hil shell: no running emulator found (start one with 'hil run' or "
                  "'hil fly'), or give --port", file=sys.stderr)
            return 1
        port = int(info["console_tcp"])
    try:
        if command is not None:
            sys.stdout.write(run_command(port, command, timeout_s))
            return 0
        return _interactive(port, board)
    except (ConnectionError, OSError, TimeoutError) as exc:
        print(f"hil shell: console on 127.0.0.1:{port}: {exc}", file=sys.stderr)
        return 1


def _interactive(port: int, board: str = "FMU") -> int:
    sock = socket.create_connection(("127.0.0.1", port))
    sock.setblocking(False)
    sel = selectors.DefaultSelector()
    sel.register(sock, selectors.EVENT_READ, "sock")
    sel.register(sys.stdin, selectors.EVENT_READ, "stdin")
    print(f"hil shell: connected to the {board} console on 127.0.0.1:{port} "
          f"(end of input to leave)", file=sys.stderr)
    sock.sendall(b"\r")
    try:
        while True:
            for key, _ in sel.select():
                if key.data == "sock":
                    data = sock.recv(4096)
                    if not data:
                        return 0
                    sys.stdout.write(data.decode("utf-8", "replace"))
                    sys.stdout.flush()
                else:
                    line = sys.stdin.readline()
                    if not line:
                        return 0
                    sock.sendall(line.rstrip("\n").encode() + b"\r")
    except KeyboardInterrupt:
        return 130
    finally:
        sock.close()
