"""Line noise on a UART's RX pin: bit errors at a bit-error rate, and lost bytes.

What a noisy or marginal serial line does to an STM32 USART receiver, frame by frame (start
bit, data bits LSB first, optional parity, stop bits, in the transmitter's format):

* a flipped data bit changes the byte; with parity enabled an odd number of flips among the
  data and parity bits sets PE (the byte is still delivered, as the STM32 does);
* a flipped first stop bit sets FE (the byte is delivered with FE);
* a flipped start bit means the receiver never saw that frame begin: the byte is lost (the
  receiver resynchronises on a later falling edge; the emulator does not model the garbage a
  mid-frame resynchronisation can produce);
* ``drop_rate`` loses whole bytes independently of the bit errors (a connector that opens for
  a character time, a buffer that cannot take a byte).

Errors are drawn with a seeded :class:`random.Random` (seed = board seed and the UART's name),
as gaps between errors (geometric), so a clean line costs one comparison per burst and a
noisy one a few operations per error. With no fault installed the UART's ``receive`` checks one
attribute per burst (``Uart.line_noise``) and goes on.
"""

from __future__ import annotations

import math
import random
from typing import TYPE_CHECKING

from board.uart_line import FE, PE, LineBreak, UartConfig

if TYPE_CHECKING:
    from board.uart import Uart

__all__ = ["LineNoise"]


class _Gaps:
    """Positions of independent events of probability ``p`` along a stream (geometric gaps)."""

    __slots__ = ("p", "rng", "_log1mp", "next")

    def __init__(self, p: float, rng: random.Random) -> None:
        self.p = p
        self.rng = rng
        self._log1mp = math.log1p(-p) if 0.0 < p < 1.0 else 0.0
        self.next = self._gap()  # events still to skip before the next one

    def _gap(self) -> int:
        p = self.p
        if p <= 0.0:
            return 1 << 62
        if p >= 1.0:
            return 0
        u = 1.0 - self.rng.random()  # (0, 1]
        return int(math.log(u) / self._log1mp)

    def take(self, n: int) -> list[int]:
        """Positions (0..n-1) of the events among the next ``n`` trials."""
        out = []
        pos = self.next
        while pos < n:
            out.append(pos)
            pos += 1 + self._gap()
        self.next = pos - n
        return out


class LineNoise:
    """Bit errors and byte drops on one UART's receiver (see the module docstring)."""

    def __init__(self, uart: Uart, bit_error_rate: float = 0.0, drop_rate: float = 0.0,
                 seed: int = 0) -> None:
        for what, v in (("bit_error_rate", bit_error_rate), ("drop_rate", drop_rate)):
            if not isinstance(v, (int, float)) or not 0.0 <= v <= 1.0:
                raise ValueError(f"UART {uart.name} line fault: {what} must be in [0, 1], "
                                 f"got {v!r}")
        self.uart = uart
        self.ber = float(bit_error_rate)
        self.drop_rate = float(drop_rate)
        rng = random.Random(f"{seed}:{uart.name}:line-noise")
        self._bits = _Gaps(self.ber, rng)
        self._drops = _Gaps(self.drop_rate, rng)
        self.bytes = 0
        self.corrupted = 0
        self.dropped = 0
        self.framing_errors = 0
        self.parity_errors = 0

    # -- installing ---------------------------------------------------------------------------

    def install(self) -> LineNoise:
        """Put this fault on the UART's RX pin (replacing any previous one)."""
        u = self.uart
        LineNoise.remove(u)
        self._receive = u.receive_clean  # the clean receiver
        u.line_noise = self
        return self

    @staticmethod
    def remove(uart: Uart) -> None:
        """Clean line again: the UART's own receiver takes the bursts directly."""
        uart.line_noise = None

    @staticmethod
    def installed(uart: Uart) -> LineNoise | None:
        noise: LineNoise | None = uart.line_noise
        return noise

    def stats(self) -> dict[str, int]:
        return {"bytes": self.bytes, "corrupted": self.corrupted, "dropped": self.dropped,
                "framing_errors": self.framing_errors, "parity_errors": self.parity_errors}

    # -- the noisy receiver -------------------------------------------------------------------

    def on_burst(self, t_start_ns: int, tx_config: UartConfig, data: bytes | LineBreak) -> None:
        if isinstance(data, LineBreak) or not data:
            self._receive(t_start_ns, tx_config, data)
            return
        data = bytes(data)
        n = len(data)
        self.bytes += n
        nb = tx_config.bits_per_frame
        flips = self._bits.take(n * nb)
        drops = self._drops.take(n)
        if not flips and not drops:
            self._receive(t_start_ns, tx_config, data)
            return
        # Per byte: XOR mask on the data, flags, or lost.
        db = tx_config.data_bits
        has_parity = tx_config.parity != "N"
        masks: dict[int, int] = {}
        flags: dict[int, int] = {}
        lost = set(drops)
        for pos in flips:
            i, bit = divmod(pos, nb)
            if bit == 0:
                lost.add(i)                      # start bit: the frame is never seen
            elif bit <= db:
                masks[i] = masks.get(i, 0) ^ (1 << (bit - 1))
            elif has_parity and bit == db + 1:
                masks[i] = masks.get(i, 0) ^ (1 << db)   # the parity bit itself
            elif bit == db + 1 + has_parity:
                flags[i] = flags.get(i, 0) | FE  # first stop bit (later ones are not checked)
        for i in lost:          # a lost frame is neither corrupted nor flagged
            masks.pop(i, None)
            flags.pop(i, None)
        out = bytearray(data)
        dmask = (1 << db) - 1
        for i, m in masks.items():
            out[i] ^= m & dmask
            if has_parity and bin(m).count("1") & 1:
                flags[i] = flags.get(i, 0) | PE
            if m & dmask:
                self.corrupted += 1
        self.dropped += len(lost)
        for f in flags.values():
            if f & FE:
                self.framing_errors += 1
            if f & PE:
                self.parity_errors += 1
        self._deliver(t_start_ns, tx_config, bytes(out), lost, flags)

    def _deliver(self, t0: int, cfg: UartConfig, data: bytes, lost: set[int],
                 flags: dict[int, int]) -> None:
        """Hand the clean runs to the receiver as sub-bursts at their own wire times and the
        flagged bytes as explicitly timed words."""
        u = self.uart
        kbits = cfg.bits_per_frame * 1_000_000_000
        baud = cfg.baud
        same_format = cfg.line_format == u.config.line_format
        n = len(data)
        i = 0
        while i < n:
            if i in lost:
                i += 1
                continue
            if i in flags and same_format:
                t_end = t0 + ((i + 1) * kbits) // baud
                u._deliver_entries([(max(u.kernel.now_ns, t_end), data[i], flags[i])], True)
                i += 1
                continue
            j = i
            while j < n and j not in lost and not (j in flags and same_format):
                j += 1
            self._receive(t0 + (i * kbits) // baud, cfg, data[i:j])
            i = j
