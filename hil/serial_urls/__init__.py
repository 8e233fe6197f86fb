"""pyserial URL handlers of the emulator: ``hil://TELEM2`` (pyserial's
``protocol_handler_packages`` mechanism, pyserial docs "URL Handlers").

Importing this package appends it to ``serial.protocol_handler_packages``, after which
``serial.serial_for_url("hil://TELEM2")`` reaches TELEM2 of the running ``hil fly``
(see :mod:`hil.serial_urls.protocol_hil`). pyserial has no plug-in entry point, so a program
needs the one import (``import hil.serial_urls``) or the same ``append`` itself.
"""

from __future__ import annotations

import serial

__all__ = ["install"]


def install() -> None:
    """Register the handlers (idempotent; done on import)."""
    if __name__ not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(__name__)


install()
