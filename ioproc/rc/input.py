"""RC input multiplexer: which receiver the IO listens to, RC loss, and what it reports.

The IO has three RC inputs: the DSM port (USART1 RX; DSM, ST24 and SUMD share it), the S.BUS
port (USART3 RX) and PPM on PA8 (TIM1 capture). PX4IO polls all of them from its main loop;
here every input is pushed as it arrives with its timestamp, and the RC-loss check runs on
every input and on :meth:`RcInput.tick` (call it from the IO main loop, e.g. every 1 ms).

Arbitration eras (reference §3.7):

``"e14"``
    every decoder runs on every input; whichever source produced the latest frame owns the
    channel set ("connect only one receiver").
``"2018"``
    S.BUS bytes are decoded only while none of DSM/ST24/SUMD is active; the DSM port only while
    neither S.BUS nor PPM is active, and on it ST24 only if neither DSM nor SUMD is active,
    SUMD only if neither DSM nor ST24 is; PPM always. A source stays active until 200 ms
    without frames, which is what lets the IO switch receivers.

RC loss: more than 200 ms without a frame from any source clears the source flags and RC_OK,
the channel count drops to 0 and the latched RC_LOST alarm is set (the FMU clears it with
:meth:`clear_rc_lost_alarm`). A receiver failsafe (S.BUS failsafe bit, SUMD 0x81) keeps RC_OK
but sets ``failsafe``. RSSI: S.BUS per era (E14: 255, 100 on frame lost, 0 on failsafe; 2015+:
100, or 50 on frame lost/failsafe), DSM from the dBm byte when present, ST24 from the packet,
SUMD 100, PPM and DSM without a dBm byte unknown (None); forced to 0 while RC is lost. An RSSI
ADC is not modelled. ST24 packets are used only when their lost count is 0 (PX4 2016+).
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Final

from ioproc.rc.common import IO_MAX_CHANNELS
from ioproc.rc.dsm import DsmDecoder
from ioproc.rc.ppm import PpmDecoder
from ioproc.rc.sbus import FLAG_FAILSAFE, FLAG_FRAME_LOST, SbusDecoder
from ioproc.rc.st24 import St24Decoder
from ioproc.rc.sumd import SumdDecoder

RC_LOST_US: Final = 200_000

SBUS: Final = "sbus"
DSM: Final = "dsm"
ST24: Final = "st24"
SUMD: Final = "sumd"
PPM: Final = "ppm"
_DSM_PORT = (DSM, ST24, SUMD)


class RcInput:
    """The IO's RC front end: decoders, arbitration, RC-loss timeout, reported state."""

    def __init__(self, *, arbitration: str = "e14", rc_lost_us: int = RC_LOST_US,
                 sbus: SbusDecoder | None = None, dsm: DsmDecoder | None = None,
                 st24: St24Decoder | None = None, sumd: SumdDecoder | None = None,
                 ppm: PpmDecoder | None = None) -> None:
        if arbitration not in ("e14", "2018"):
            raise ValueError(f"arbitration must be 'e14' or '2018', not {arbitration!r}")
        self.arbitration = arbitration
        self.rc_lost_us = rc_lost_us
        self.sbus = sbus or SbusDecoder()
        self.dsm = dsm or DsmDecoder()
        self.st24 = st24 or St24Decoder()
        self.sumd = sumd or SumdDecoder()
        self.ppm = ppm or PpmDecoder()
        self.channels: list[int] = []
        self.channel_count = 0
        #: Protocol of the last accepted frame, None before the first one and after RC loss.
        self.source: str | None = None
        self.rc_ok = False
        #: Latched ALARMS.RC_LOST.
        self.rc_lost_alarm = False
        self.failsafe = False
        self.frame_lost = False
        self.rssi: int | None = 0
        self.frame_count = 0
        self.last_frame_us: int | None = None
        self._source_last: dict[str, int] = {}

    # -- state --------------------------------------------------------------------------------
    @property
    def active_sources(self) -> frozenset[str]:
        """Source flags (RC_SBUS, RC_DSM, RC_PPM, RC_ST24, RC_SUMD) currently set."""
        return frozenset(self._source_last)

    @property
    def dsm_11bit(self) -> bool:
        return self.dsm.dsm_11bit

    @property
    def frame_drops(self) -> int:
        """Drop counter of the current source (RAW_RC FRAME_DROP)."""
        dec = self._decoder(self.source) if self.source else None
        return dec.frame_errors if dec is not None else 0

    def _decoder(self, name: str):
        return getattr(self, name)

    def clear_rc_lost_alarm(self) -> None:
        self.rc_lost_alarm = False

    # -- inputs -------------------------------------------------------------------------------
    def feed_sbus_port(self, t_us: int, data: bytes | Iterable[int]) -> bool:
        """Bytes from USART3; True if they produced an accepted frame."""
        self.tick(t_us)
        if self.arbitration == "2018" and self._source_last.keys() & set(_DSM_PORT):
            return False
        if self.sbus.feed(t_us, data):
            return self._accept(SBUS, t_us)
        return False

    def feed_dsm_port(self, t_us: int, data: bytes | Iterable[int]) -> bool:
        """Bytes from USART1 (DSM, ST24 and SUMD share the port)."""
        self.tick(t_us)
        active = self._source_last.keys()
        if self.arbitration == "2018":
            if SBUS in active or PPM in active:
                return False
            run_st24 = DSM not in active and SUMD not in active
            run_sumd = DSM not in active and ST24 not in active
        else:
            run_st24 = run_sumd = True
        data = bytes(data)
        accepted = False
        if self.dsm.feed(t_us, data):
            accepted |= self._accept(DSM, t_us)
        if run_st24 and self.st24.feed(t_us, data) and self.st24.lost_count == 0:
            accepted |= self._accept(ST24, t_us)
        if run_sumd and self.sumd.feed(t_us, data):
            accepted |= self._accept(SUMD, t_us)
        return accepted

    def feed_ppm_edge(self, t_us: int, level: int | None = None) -> bool:
        """A PPM edge at ``t_us`` (absolute µs)."""
        self.tick(t_us)
        if self.ppm.feed_edge(t_us, level):
            return self._accept(PPM, t_us)
        return False

    def feed_ppm_capture(self, t_us: int, count: int, level: int | None = None, *,
                         overflow: bool = False) -> bool:
        """A TIM1 CH1 capture (16-bit ``count``, CC1OF ``overflow``) seen by the ISR at ``t_us``."""
        self.tick(t_us)
        if self.ppm.feed_capture(count, level, overflow=overflow, t_us=t_us):
            return self._accept(PPM, t_us)
        return False

    def tick(self, now_us: int) -> None:
        """Expire silent sources and detect RC loss (the IO's controls_tick check)."""
        lost = self.rc_lost_us
        src = self._source_last
        for name in [n for n, t in src.items() if now_us - t > lost]:
            del src[name]
        last = self.last_frame_us if self.last_frame_us is not None else 0
        if now_us - last > lost:
            if self.rc_ok or self.source is not None:
                self.rc_ok = False
                self.source = None
                self.channel_count = 0
                self.channels = []
            src.clear()
            self.rc_lost_alarm = True
            self.rssi = 0

    # -- arbitration result -------------------------------------------------------------------
    def _accept(self, name: str, t_us: int) -> bool:
        dec = self._decoder(name)
        n = min(dec.channel_count, IO_MAX_CHANNELS)
        self.channels = list(dec.channels[:n])
        self.channel_count = n
        self.source = name
        self.rc_ok = True
        self.last_frame_us = t_us
        self.frame_count += 1
        self._source_last[name] = t_us
        self.failsafe = bool(dec.failsafe)
        self.frame_lost = bool(dec.frame_lost)
        if name == SBUS:
            self.rssi = self._sbus_rssi(dec.flags)
        else:
            self.rssi = dec.rssi
        return True

    def _sbus_rssi(self, flags: int) -> int:
        if self.arbitration == "e14":
            if flags & FLAG_FAILSAFE:
                return 0
            return 100 if flags & FLAG_FRAME_LOST else 255
        return 50 if flags & (FLAG_FRAME_LOST | FLAG_FAILSAFE) else 100
