"""Register bit masks as plain ints for the main loop.

Why: ``IntFlag`` arithmetic builds a new enum member per operation, which made one IO pass
several times slower than the work it does. The enums in :mod:`ioproc.protocol` stay the single
definition; these classes only copy their values once, at import.
"""

from __future__ import annotations

from enum import IntFlag
from typing import Any

from ioproc.protocol import Alarms, Arming, Features, RawRcFlags, StatusFlags

__all__ = ["AL", "AR", "FE", "RF", "SF"]


def _ints(flags: type[IntFlag]) -> Any:
    return type(f"{flags.__name__}Bits", (), {f.name: int(f) for f in flags})


SF = _ints(StatusFlags)
AL = _ints(Alarms)
AR = _ints(Arming)
FE = _ints(Features)
RF = _ints(RawRcFlags)
