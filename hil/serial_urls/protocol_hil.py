"""``hil://NAME``: an emulated UART of the running ``hil fly`` as a pyserial port.

``NAME`` is what ``hil fly`` prints and announces (``TELEM1``, ``TELEM2``, ``CONSOLE``; case
does not matter); ``hil://TELEM2?port=N`` skips the discovery and uses the UART's TCP port N on
127.0.0.1. The URL becomes pyserial's own ``socket://127.0.0.1:<port>`` (the UART's bridge in
``hil fly`` serves every TCP client with the bytes the board transmits and sends what they
write into its RX line), so the port behaves as a network serial port: ``baudrate`` and the
other settings are accepted and ignored, the emulated UART keeps the configuration the firmware
gave it (57600 8N1 for TELEM links).
"""

from __future__ import annotations

import urllib.parse
from typing import Any

from serial.urlhandler import protocol_socket

__all__ = ["Serial", "resolve", "serial_class_for_url"]

Serial = protocol_socket.Serial


def resolve(url: str) -> tuple[str, int]:
    """(name, TCP port) of ``hil://NAME[?port=N]``; ValueError (pyserial's SerialException is
    raised by pyserial around it) when no running emulator announces that UART."""
    parts = urllib.parse.urlsplit(url)
    if parts.scheme.lower() != "hil":
        raise ValueError(f"expected a hil:// URL, got {url!r}")
    name = (parts.netloc + parts.path).strip("/").upper()
    if not name:
        raise ValueError(f"hil:// URL without a UART name: {url!r} (e.g. hil://TELEM2)")
    query = urllib.parse.parse_qs(parts.query)
    if "port" in query:
        try:
            return name, int(query["port"][0])
        except ValueError:
            raise ValueError(f"hil:// URL: port must be an integer: {url!r}") from None
    from hil.shell_client import pid_alive, runtime_dir
    import json

    best: dict[str, Any] | None = None
    for f in runtime_dir().glob("*.json"):
        try:
            info = json.loads(f.read_text())
        except (OSError, ValueError):
            continue
        uarts = info.get("uart") if isinstance(info, dict) else None
        if isinstance(uarts, dict) and isinstance(uarts.get(name), int) \
                and pid_alive(int(info.get("pid", 0))) \
                and (best is None or info.get("started", 0) > best.get("started", 0)):
            best = info
    if best is None:
        raise ValueError(f"no running emulator announces UART {name!r} (start 'hil fly'; it "
                         f"prints the hil:// names)")
    return name, int(best["uart"][name])


def serial_class_for_url(url: str) -> tuple[str, type]:
    """pyserial's hook: the URL rewritten to ``socket://`` and the class that opens it."""
    _name, port = resolve(url)
    return f"socket://127.0.0.1:{port}", Serial
