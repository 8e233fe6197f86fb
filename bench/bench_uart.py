"""UART throughput: bytes/s moved through a connected pair at 1.5 Mbaud 8N1.

One side writes 68-byte bursts (a PX4IO packet's size); the other side's IDLE interrupt reads
the buffer and has the first side write the next burst, as on the FMU-IO link. The figure is
bytes delivered per wall-clock second, median of 5 runs.
"""

from __future__ import annotations

from bench._util import median_rate
from board.kernel import Kernel
from board.uart import Uart, UartConfig, UartWire

BURST = 68
N_BURSTS = 20_000
CONFIG = UartConfig(baud=1_500_000)


def _run() -> int:
    kernel = Kernel("bench")
    a = Uart(kernel, "a", CONFIG)
    b = Uart(kernel, "b", CONFIG)
    UartWire(a, b)
    payload = bytes(range(BURST))
    state = [N_BURSTS, 0]  # bursts left, bytes read

    def idle(t_ns: int) -> None:
        state[1] += len(b.read())
        state[0] -= 1
        if state[0] > 0:
            a.write(payload)

    b.on_idle(idle)
    a.write(payload)
    kernel.run(1 << 62)
    if state[1] != N_BURSTS * BURST:
        raise RuntimeError(f"bench_uart: moved {state[1]} bytes, expected {N_BURSTS * BURST}")
    return state[1]


def bench_uart_bytes_per_s() -> float:
    """Median over 5 runs of bytes/s through a connected pair (68-byte bursts, IDLE + read)."""
    return median_rate(_run)


if __name__ == "__main__":
    print(f"uart_bytes_per_s: {bench_uart_bytes_per_s():,.0f}")
