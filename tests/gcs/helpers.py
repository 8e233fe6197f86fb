"""The GCS client with the firmware's dialect: development's and component information
messages decode (hil.gcs parses with ``common``, where they would be unknown ids)."""

from __future__ import annotations

from typing import Any

from firmware.modules.mavlink.dialect import mav


def use_dialect(gcs: Any) -> Any:
    """Make ``gcs`` parse what it receives with the firmware's dialect; returns the module."""
    rx = mav.MAVLink(None, gcs.rx.srcSystem, gcs.rx.srcComponent)
    rx.robust_parsing = True
    gcs.rx = rx
    return mav
