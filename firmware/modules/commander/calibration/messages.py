"""The calibration STATUSTEXT protocol QGroundControl's sensor page parses.

QGC runs its calibration page as a state machine driven by these texts (PX4's
``calibration_messages.h``): the version number in "calibration started" ("2") tells it to show
the visual six-side page, "progress <n>" moves its bar, "<side> orientation detected" and
"<side> side done, rotate to a different side" colour the side pictures, "calibration done" and
"calibration failed" end it. The texts must stay exactly as they are.
"""

from __future__ import annotations

from typing import Final

__all__ = ["CANCELLED", "SIDE_NAMES", "already_done", "detected", "done", "failed", "pending",
           "progress", "side_done", "started"]

#: PX4's side order and names: index 0 tail down (+g on x), 1 nose down (-g on x), 2 left
#: side down (+g on y), 3 right side down (-g on y), 4 upside down (+g on z), 5 right side up
SIDE_NAMES: Final = ("back", "front", "left", "right", "up", "down")
CANCELLED: Final = "[cal] calibration cancelled"
HOLD_STILL: Final = "[cal] hold vehicle still on a pending side"
REST_DETECTED: Final = "[cal] detected rest position, hold still..."
MOTION_DETECTED: Final = "[cal] detected motion, hold still..."
MOTION_RETRY: Final = "[cal] motion, retrying.."
READING_SENSOR: Final = "[cal] calibration failed: reading sensor"


def started(kind: str) -> str:
    return f"[cal] calibration started: 2 {kind}"


def done(kind: str) -> str:
    return f"[cal] calibration done: {kind}"


def failed(why: str) -> str:
    return f"[cal] calibration failed: {why}"


def progress(percent: int) -> str:
    return f"[cal] progress <{max(0, min(100, percent))}>"


def pending(sides_done: list[bool]) -> str:
    return "[cal] pending:" + "".join(f" {SIDE_NAMES[i]}" for i in range(6) if not sides_done[i])


def detected(side: int) -> str:
    return f"[cal] {SIDE_NAMES[side]} orientation detected"


def side_done(side: int) -> str:
    return f"[cal] {SIDE_NAMES[side]} side done, rotate to a different side"


def already_done(side: int) -> str:
    return f"[cal] {SIDE_NAMES[side]} side already completed"
