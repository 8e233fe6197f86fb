"""PX4IO link throughput: FMU encode + IO request handler + FMU decode, per second.

A typical E14 cycle of the px4io driver: WRITE 8 controls (page 51), READ status flags ..
VRSSI (page 1 offset 2, 6 regs), READ raw RC (page 4 offset 0, 15 regs). The figure counts
transactions (three per cycle), so it bounds how often the emulated FMU can talk to the IO.
"""

from __future__ import annotations

from bench._util import median_rate
from ioproc.pages import IoPages
from ioproc.protocol import (
    PageNo,
    decode_reply,
    encode_read,
    encode_write,
    float_to_reg,
    handle_request,
)

N_CYCLES = 5_000


def _run() -> int:
    regs = IoPages()
    t_us = 0
    for i in range(N_CYCLES):
        t_us += 2500
        controls = [float_to_reg(((i + k) % 200 - 100) / 100.0) for k in range(8)]
        for request in (encode_write(PageNo.CONTROLS, 0, controls),
                        encode_read(PageNo.STATUS, 2, 6),
                        encode_read(PageNo.RAW_RC_INPUT, 0, 15)):
            reply = decode_reply(handle_request(request, regs, t_us))
            if not reply.ok:
                raise RuntimeError(f"IO refused {request.hex()}")
    return 3 * N_CYCLES


def bench_px4io_transactions_per_s() -> float:
    """Median over 5 runs of complete request/reply transactions per second."""
    return median_rate(_run)


if __name__ == "__main__":
    print(f"px4io_transactions_per_s: {bench_px4io_transactions_per_s():.0f}")
