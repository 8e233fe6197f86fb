"""A Spektrum DSM2/DSMX satellite: 16-byte frames, 115200 8N1, every 11 or 22 ms.

The bytes come from the IO decoder's own encoder (:func:`ioproc.rc.encode_dsm_frame` and
``dsm_word``). Modes and their system byte (byte 1):

=========  ======  ==========  ======
mode       period  resolution  system
=========  ======  ==========  ======
dsm2_22    22 ms   10-bit      0x01
dsm2_11    11 ms   11-bit      0x12
dsmx_22    22 ms   11-bit      0xA2
dsmx_11    11 ms   11-bit      0xB2
=========  ======  ==========  ======

Channel order on the wire is Spektrum's (0 throttle, 1 aileron, 2 elevator, 3 rudder, ...);
PX4 moves IDs 0, 1, 2 to slots 2, 0, 1, so transmitter channel 1 (roll) goes out as ID 1,
channel 2 (pitch) as ID 2 and channel 3 (throttle) as ID 0. More than seven channels do not fit
one frame: they are spread over consecutive frames of seven (the second half with the phase bit
set in 2048 mode), so a decoder sees each channel every second frame.

Values: µs from the transmitter become the position PX4's scaling decodes to the nearest µs
(exact in 11-bit mode, whose 0.583 µs step is finer than 1 µs; within 1 µs in 10-bit mode).

Byte 0 counts fades (RF frames lost since power-up, as an 8-bit counter) or, with
``rssi_dbm`` set, carries that signed dBm value as telemetry satellites do. Link loss: a
satellite simply stops sending; there is no failsafe flag in DSM, PX4 notices by the 200 ms
RC timeout. A lost RF frame is a missing frame on the wire and one more fade.
"""

from __future__ import annotations

from bisect import bisect_left

from hil.rc.receiver import Receiver
from hil.rc.transmitter import Transmitter
from ioproc.rc.dsm import DSM10_TO_US, DSM11_TO_US, dsm_word, encode_dsm_frame

__all__ = ["DSM_LINE", "DSM_MODES", "DsmReceiver", "us_to_dsm_pos"]

DSM_LINE = (115_200, 8, "N", 1, False)
#: mode → (frame period ns, resolution bits, system byte)
DSM_MODES: dict[str, tuple[int, int, int]] = {
    "dsm2_22": (22_000_000, 10, 0x01),
    "dsm2_11": (11_000_000, 11, 0x12),
    "dsmx_22": (22_000_000, 11, 0xA2),
    "dsmx_11": (11_000_000, 11, 0xB2),
}
#: PX4 output slot → Spektrum channel ID (inverse of PX4's 0→2, 1→0, 2→1 remap).
_SLOT_TO_ID = (1, 2, 0)
_WORDS_PER_FRAME = 7
#: 2048 mode carries IDs 0..11 plainly (12 is X-Plus, not modelled).
_MAX_CHANNELS = 12


def _inverse(table: tuple[int, ...]) -> list[int]:
    """µs (from table[0] to table[-1]) → the position whose PX4 value is nearest."""
    inv = []
    for us in range(table[0], table[-1] + 1):
        i = bisect_left(table, us)  # first position decoding to ≥ us (tables are monotonic)
        if i > 0 and us - table[i - 1] < table[i] - us:
            i -= 1
        inv.append(i)
    return inv


_INV = {11: (_inverse(DSM11_TO_US), DSM11_TO_US[0], DSM11_TO_US[-1]),
        10: (_inverse(DSM10_TO_US), DSM10_TO_US[0], DSM10_TO_US[-1])}


def us_to_dsm_pos(us: int, bits: int = 11) -> int:
    """Servo position PX4's 2021+ scaling turns back into ``us`` (nearest; clamped)."""
    inv, lo, hi = _INV[bits]
    return inv[min(hi, max(lo, int(us))) - lo]


class DsmReceiver(Receiver):
    """Spektrum satellite on a world port (default ``rc_dsm``; give ``port="rc_sbus"`` for the
    "DSM receiver on the S.BUS connector" fault)."""

    kind = "dsm"

    def __init__(self, tx: Transmitter, *, port: str = "rc_dsm", mode: str = "dsmx_11",
                 channels: int = 8, rssi_dbm: int | None = None, **kwargs: object) -> None:
        if mode not in DSM_MODES:
            raise ValueError(f"DSM mode must be one of {', '.join(DSM_MODES)}, not {mode!r}")
        if not 1 <= channels <= min(_MAX_CHANNELS, tx.n_channels):
            raise ValueError(f"DSM channels must be 1..{min(_MAX_CHANNELS, tx.n_channels)}, "
                             f"not {channels}")
        if rssi_dbm is not None and not -128 <= rssi_dbm < 0:
            raise ValueError(f"rssi_dbm must be -128..-1, not {rssi_dbm}")
        period_ns, self.bits, self.system = DSM_MODES[mode]
        kwargs.setdefault("period_ns", period_ns)
        super().__init__(tx, port=port, **kwargs)  # type: ignore[arg-type]
        self.mode = mode
        self.channels = channels
        self.rssi_dbm = rssi_dbm
        self._groups = [list(range(i, min(i + _WORDS_PER_FRAME, channels)))
                        for i in range(0, channels, _WORDS_PER_FRAME)]

    @property
    def fades(self) -> int:
        return self.lost_total & 0xFF

    def frame_bytes(self, values: list[int], k: int = 0) -> bytes:
        """Frame ``k`` of the sequence: its group of channel slots, Spektrum IDs on the wire."""
        group = k % len(self._groups)
        bits = self.bits
        words = []
        for slot in self._groups[group]:
            cid = _SLOT_TO_ID[slot] if slot < 3 else slot
            words.append(dsm_word(cid, us_to_dsm_pos(values[slot], bits), bits=bits,
                                  phase=group == 1))
        b0 = self.fades if self.rssi_dbm is None else self.rssi_dbm & 0xFF
        return encode_dsm_frame(words, fades=b0, system=self.system)

    def _emit(self, t_ns: int, k: int, rf_ok: bool) -> int:
        if not rf_ok or self.held is None:
            return self.period_ns  # a satellite without the link is silent
        values = self.held
        byte_prob, spike_prob, rng = self.glitches(t_ns, k)
        table = DSM11_TO_US if self.bits == 11 else DSM10_TO_US
        if rng is not None and rng.random() < spike_prob:
            values = list(values)
            values[rng.randrange(self.channels)] = table[rng.randrange(len(table))]
        frame = self.frame_bytes(values, k)
        if rng is not None and rng.random() < byte_prob:
            damaged = bytearray(frame)
            damaged[rng.randrange(len(frame))] ^= rng.randrange(1, 256)
            frame = bytes(damaged)
        self._out.append((self.port, t_ns, (*DSM_LINE, frame)))
        self.frames_sent += 1
        return self.period_ns
