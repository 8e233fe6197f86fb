"""Mismatched-baud UART decoding: frames/s through the bit-level LineDecoder, old vs new.

The GPS driver scans baud rates, so the receiver spends seconds listening at the wrong baud:
a u-blox at 9600 talking NMEA while the FMU listens at 38400, or at 115200 talking UBX while
the FMU listens at 57600. Every such byte goes through :class:`board.uart_line.LineDecoder`.
This bench replays that traffic the way ``board/uart.py`` drives the decoder (each write is fed
and decoded at write time with ``final=False``; ``final=True`` runs once the waveform's end is
in the past) through the current decoder and through the original Fraction-based one kept as
the test oracle, checks they agree, and prints decoded frames per wall-clock second for both.

Run from the repository root: ``python -m bench.bench_uart_mismatch``.
"""

from __future__ import annotations

import random
from collections.abc import Callable
from typing import Any

from bench._util import median_rate
from board.uart_line import NS_PER_S, LineDecoder, UartConfig

Burst = tuple[int, int, UartConfig, bytes]  # (write time ns, t_start ns, tx config, data)

_NMEA = [
    "$GPGGA,{t},4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47\r\n",
    "$GPGSA,A,3,04,05,,09,12,,,24,,,,,2.5,1.3,2.1*39\r\n",
    "$GPRMC,{t},A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*6A\r\n",
    "$GPVTG,054.7,T,034.4,M,005.5,N,010.2,K*48\r\n",
    "$GPGSV,2,1,08,01,40,083,46,02,17,308,41,12,07,344,39,14,22,228,45*75\r\n",
]


def _queue(epochs: list[tuple[int, list[bytes]]], cfg: UartConfig) -> list[Burst]:
    """Writes queued back to back at each epoch, as ``Uart.write`` times them."""
    out: list[Burst] = []
    idle = 0
    kbits = cfg.bits_per_frame * NS_PER_S
    for now, writes in epochs:
        for data in writes:
            t0 = max(idle, now)
            idle = t0 + (len(data) * kbits) // cfg.baud
            out.append((now, t0, cfg, data))
    return out


def nmea_at_38400(seconds: int = 3) -> tuple[list[Burst], UartConfig]:
    """A 9600-baud receiver's 1 Hz NMEA epochs, heard by an FMU listening at 38400."""
    epochs = []
    for s in range(seconds):
        writes = [line.format(t=f"{123519 + s:06d}").encode() for line in _NMEA]
        epochs.append((s * NS_PER_S + 137_000, writes))
    return _queue(epochs, UartConfig(9600)), UartConfig(38_400)


def ubx_at_57600(seconds: int = 3, rate_hz: int = 5) -> tuple[list[Burst], UartConfig]:
    """A 115200-baud receiver's UBX (NAV-PVT, NAV-DOP, NAV-SAT sized), heard at 57600."""
    rng = random.Random(1)
    epochs = []
    for k in range(seconds * rate_hz):
        writes = [b"\xb5\x62" + rng.randbytes(n) for n in (98, 24, 206)]
        epochs.append((k * NS_PER_S // rate_hz + 53_000, writes))
    return _queue(epochs, UartConfig(115_200)), UartConfig(57_600)


def drive(decoder: Any, bursts: list[Burst], rx: UartConfig) -> list[tuple]:
    """Call ``decoder`` in the order ``Uart._receive_slow``/``_decode_final`` would.

    Returns every ``decode`` result, so two decoders can be compared call by call.
    """
    results: list[tuple] = []
    wake: int | None = None
    for now, t0, tx, data in bursts:
        if wake is not None and wake < now:
            results.append(decoder.decode(rx, True))
            wake = results[-1][1]
        decoder.feed(t0, tx, data, rx)
        results.append(decoder.decode(rx, False))
        wake = results[-1][1]
    while wake is not None:
        results.append(decoder.decode(rx, True))
        wake = results[-1][1]
    return results


def _frames(results: list[tuple]) -> int:
    return sum(len(r[0]) for r in results)


def _rate(make: Callable[[], Any], workload: tuple[list[Burst], UartConfig], runs: int) -> float:
    bursts, rx = workload
    return median_rate(lambda: _frames(drive(make(), bursts, rx)), runs)


def bench_uart_mismatch_frames_per_s() -> float:
    """Median frames/s of the current decoder over both GPS-like workloads (a figure in the
    style of ``bench/__init__.py``'s FIGURES)."""
    work = [nmea_at_38400(), ubx_at_57600()]
    return median_rate(lambda: sum(_frames(drive(LineDecoder(), b, rx)) for b, rx in work))


def main() -> None:
    from tests.board._line_decoder_reference import LineDecoder as OldDecoder

    for name, workload in (("NMEA 9600 -> rx 38400", nmea_at_38400()),
                           ("UBX 115200 -> rx 57600", ubx_at_57600())):
        bursts, rx = workload
        old_res = drive(OldDecoder(), bursts, rx)
        new_res = drive(LineDecoder(), bursts, rx)
        if old_res != new_res:
            raise SystemExit(f"{name}: new decoder disagrees with the reference")
        old = _rate(OldDecoder, workload, 3)
        new = _rate(LineDecoder, workload, 5)
        print(f"{name}: {_frames(new_res)} frames from {len(bursts)} writes (identical); "
              f"old {old:,.0f} frames/s, new {new:,.0f} frames/s, x{new / old:.1f}")


if __name__ == "__main__":
    main()
