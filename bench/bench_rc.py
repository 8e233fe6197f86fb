"""RC decoding throughput: S.BUS frames decoded per second, fed byte by byte with timestamps.

The frames are built once (varying channel values, S.BUS2 end bytes) and fed the way the IO's
USART3 delivers them: one byte every 120 µs (8E2 at 100 kbit/s), a frame every 7 ms.
"""

from __future__ import annotations

from bench._util import median_rate
from ioproc.rc.sbus import SbusDecoder, encode_sbus_frame

N_FRAMES = 20_000
FRAME_PERIOD_US = 7_000
BYTE_US = 120

_FRAMES = [
    encode_sbus_frame([(k * 37 + 101 * i) % 2048 for i in range(16)], end=(0, 4, 0x14)[k % 3])
    for k in range(64)
]


def _run() -> int:
    d = SbusDecoder()
    fb = d.feed_byte
    frames = _FRAMES
    decoded = 0
    for k in range(N_FRAMES):
        t = k * FRAME_PERIOD_US
        for b in frames[k & 63]:
            if fb(t, b):
                decoded += 1
            t += BYTE_US
    assert decoded == N_FRAMES == d.frames
    return decoded


def bench_sbus_frames_decoded_per_s() -> float:
    """Median of 5 runs of S.BUS frames decoded per second of wall time."""
    return median_rate(_run)


if __name__ == "__main__":
    print(f"sbus_frames_decoded_per_s: {bench_sbus_frames_decoded_per_s():,.0f}")
