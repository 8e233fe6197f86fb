"""Readers for the recorded RC fixtures in ../shared/fixtures (data only, see its README)."""

from __future__ import annotations

import json
import struct
from functools import cache
from pathlib import Path

FIXTURES = Path(__file__).resolve().parents[3] / "shared" / "fixtures"
PX4_RC = FIXTURES / "px4_rc"
ARDUPILOT_VECTORS = FIXTURES / "ardupilot_rc" / "rcprotocoltest_vectors.json"

#: PX4's rc_tests throw away the header and the first 19 data rows.
UPSTREAM_SKIP_LINES = 20

_F32 = struct.Struct("<f")


def _f32(x: float) -> float:
    return _F32.unpack(_F32.pack(x))[0]


def time_to_us(t_s: str) -> int:
    """PX4's test conversion: (uint64)(float32(t) * 1e6f), the product also in float32."""
    return int(_f32(_f32(float(t_s)) * _f32(1e6)))


@cache
def read_capture(name: str, skip_lines: int = UPSTREAM_SKIP_LINES) -> tuple[tuple[int, int], ...]:
    """(t_us, byte) rows of a logic-analyser CSV capture, after PX4's skip."""
    rows = []
    with open(PX4_RC / name) as f:
        for i, line in enumerate(f):
            if i < skip_lines or not line.strip():
                continue
            t, v = line.split(",")[:2]
            rows.append((time_to_us(t), int(v, 16)))
    return tuple(rows)


@cache
def ardupilot_vectors() -> dict:
    with open(ARDUPILOT_VECTORS) as f:
        return json.load(f)["vectors"]


def replay_ardupilot(vector: dict, passes: int) -> list[tuple[int, int]]:
    """(t_us, byte) stream the way ArduPilot's RCProtocolTest replays a vector.

    Bytes follow each other at the UART character time (10 bits at 115200, 12 at 100000 8E2);
    ``pause_at`` inserts 10 ms before every pause_at-th byte; each pass is followed by 10 ms.
    """
    bits = 12 if vector["baudrate"] == 100000 else 10
    byte_us = round(bits * 1e6 / vector["baudrate"])
    out = []
    t = 0
    data = vector["bytes"]
    pause = vector["pause_at"]
    for _ in range(passes):
        for i, b in enumerate(data):
            if i and pause and i % pause == 0:
                t += 10_000
            out.append((t, b))
            t += byte_us
        t += 10_000
    return out
