"""A Futaba-style S.BUS receiver: 25-byte frames, 100 kbit/s 8E2 inverted, every 14 or 7 ms.

The frame bytes come from the IO decoder's own encoder (:func:`ioproc.rc.encode_sbus_frame`),
so the packing exists once. A frame leaves as one ``uart`` record stamped with its first start
bit; its 25 bytes follow back to back, 120 µs each (12 bit times), 3 ms per frame, which leaves
the ≥ 4 ms of silence decoders synchronise on.

Values: µs from the transmitter become the 11-bit position PX4 decodes back to the same µs
(its 0.625 µs/count step is finer than 1 µs, so every whole µs in 874…2153 round-trips
exactly). Channels 17 and 18 ride in the flags byte as digital channels (on above centre).

Link loss (what Futaba and FrSky receivers do): frames keep coming every period; each one
carries the frame-lost flag and the last good values while the loss is shorter than the
failsafe delay; after it the failsafe bit is set as well and the channels go to the failsafe
preset (``on_loss="failsafe"``), stay at the last values (``"hold"``), or the receiver stops
sending altogether (``"no_pulses"``, an option some FrSky receivers offer).
"""

from __future__ import annotations

from hil.rc.receiver import Receiver
from hil.rc.transmitter import Transmitter
from ioproc.rc.sbus import SBUS_RAW_TO_US, encode_sbus_frame

__all__ = ["SBUS_LINE", "SbusReceiver", "us_to_sbus_raw"]

#: (baud, data bits, parity, stop bits) of S.BUS; inversion is a receiver option.
SBUS_LINE = (100_000, 8, "E", 2)
SBUS_PERIOD_NS = 14_000_000
SBUS_FAST_PERIOD_NS = 7_000_000
_S2_END_BYTES = (0x04, 0x14, 0x24, 0x34)


def _inverse_table() -> dict[int, int]:
    inv: dict[int, int] = {}
    for raw, us in enumerate(SBUS_RAW_TO_US):
        inv.setdefault(us, raw)
    return inv


_US_TO_RAW = _inverse_table()
_MIN_US, _MAX_US = SBUS_RAW_TO_US[0], SBUS_RAW_TO_US[-1]


def us_to_sbus_raw(us: int) -> int:
    """11-bit position that PX4's scaling turns back into ``us`` (clamped to 874…2153)."""
    return _US_TO_RAW[min(_MAX_US, max(_MIN_US, int(us)))]


class SbusReceiver(Receiver):
    """S.BUS receiver on a world port (default ``rc_sbus``).

    ``high_speed`` selects the 7 ms frame interval; ``period_ns`` overrides both (other makes:
    a FrSky X8R runs at ≈9 ms). ``sbus2`` cycles the S.BUS2 end bytes 0x04/0x14/0x24/0x34
    (without telemetry slots). ``invert=False`` is a wiring fault: the signal without the
    inverter the IO expects.
    """

    kind = "sbus"

    def __init__(self, tx: Transmitter, *, port: str = "rc_sbus", high_speed: bool = False,
                 period_ns: int | None = None, on_loss: str = "failsafe", sbus2: bool = False,
                 invert: bool = True, **kwargs: object) -> None:
        if on_loss not in ("failsafe", "hold", "no_pulses"):
            raise ValueError(f"S.BUS on_loss must be 'failsafe', 'hold' or 'no_pulses', "
                             f"not {on_loss!r}")
        if period_ns is None:
            period_ns = SBUS_FAST_PERIOD_NS if high_speed else SBUS_PERIOD_NS
        super().__init__(tx, port=port, period_ns=period_ns, **kwargs)  # type: ignore[arg-type]
        self.on_loss = on_loss
        self.sbus2 = sbus2
        self.line = (*SBUS_LINE, bool(invert))

    def frame_bytes(self, values: list[int], *, frame_lost: bool = False,
                    failsafe: bool = False, k: int = 0) -> bytes:
        """The 25 bytes for channel values in µs (the first 18 used)."""
        raw = [us_to_sbus_raw(v) for v in values[:16]]
        centre = self.tx.center_us
        ch17 = len(values) > 16 and values[16] > centre
        ch18 = len(values) > 17 and values[17] > centre
        end = _S2_END_BYTES[k & 3] if self.sbus2 else 0x00
        return encode_sbus_frame(raw, ch17=ch17, ch18=ch18, frame_lost=frame_lost,
                                 failsafe=failsafe, end=end)

    def _emit(self, t_ns: int, k: int, rf_ok: bool) -> int:
        held = self.held
        if held is None:
            return self.period_ns  # never linked since power-up: the line stays idle
        frame_lost = not rf_ok
        failsafe = False
        values = held
        if frame_lost and self.in_failsafe(t_ns):
            if self.on_loss == "no_pulses":
                return self.period_ns
            failsafe = True
            if self.on_loss == "failsafe":
                values = self.tx.failsafe_us
        if self.forced_failsafe(t_ns):
            failsafe = True
        byte_prob, spike_prob, rng = self.glitches(t_ns, k)
        if rng is not None and rng.random() < spike_prob:
            values = list(values)
            values[rng.randrange(16)] = SBUS_RAW_TO_US[rng.randrange(2048)]
        frame = self.frame_bytes(values, frame_lost=frame_lost, failsafe=failsafe, k=k)
        if rng is not None and rng.random() < byte_prob:
            damaged = bytearray(frame)
            damaged[rng.randrange(len(frame))] ^= rng.randrange(1, 256)
            frame = bytes(damaged)
        self._out.append((self.port, t_ns, (*self.line, frame)))
        self.frames_sent += 1
        return self.period_ns
