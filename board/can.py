"""Emulated CAN bus and bxCAN-like controllers, bit-time accurate.

Frames are python-can :class:`can.Message` objects at the API, so a driver written against
python-can's ``send``/``recv`` shape runs here and, later, on a real bus (mind python-can's
default ``is_extended_id=True``; pass False for 11-bit identifiers). On the wire each frame
lasts its real length: SOF to the end of the CRC sequence is bit-stuffed (the CRC-15 is computed,
since it decides the stuffing), then CRC delimiter, ACK slot, ACK delimiter and 7 EOF bits, then
3 bits of interframe space before the next SOF. Timing uses exact integer arithmetic from the
SOF time: ``t = t_sof + (bits * 10**9) // bitrate``.

Fault confinement follows ISO 11898-1 with these simplifications (documented so tests can rely
on them):

- An error (ACK error or an injected corruption) is signalled by an error frame starting right
  after the ACK slot: 6 flag bits + 8 delimiter bits, then the 3-bit interframe space. Flag
  superposition from several nodes (up to 12 dominant bits) is not modelled.
- Transmit error: TEC += 8, except an ACK error seen by an error-passive transmitter (nobody
  else on the bus makes its passive error flag fail), which leaves TEC unchanged - so a lone
  node climbs to TEC 128 (error passive) and stays there instead of going bus-off.
- Receive error (injected corruption): REC += 1 on every receiving node (saturating at 255).
  Success: TEC -= 1; REC -= 1, or back to 127 when above 127.
- Error passive when TEC or REC > 127; an error-passive transmitter waits 8 extra bits
  (suspend transmission) after its own frame or error frame. Bus-off when TEC > 255: the node
  neither sends, receives nor acknowledges. Recovery takes 128 x 11 recessive bit times
  (modelled as 1408 bit times, whatever the bus traffic) after bus-off, automatically if
  ``auto_recovery`` (bxCAN ABOM), else after :meth:`CanController.recover`.
- A controller built with ``enabled=False`` is a bxCAN still in sleep/initialisation mode
  after reset: it neither sends, receives nor acknowledges until :meth:`CanController.enable`
  (the driver leaving initialisation mode).
- Wire faults (:meth:`CanBus.set_wire_fault`): CAN_H shorted to CAN_L holds the bus recessive,
  so a transmitter reads recessive back at its dominant SOF: a bit error at bit 1, TEC += 8
  (no ACK-error exception), an error flag nobody sees (6 + 8 bits) and the interframe space;
  receivers see an idle bus (no REC change), so bus-off recovery (recessive bits) still counts.
  A bit-error rate corrupts each bit with that probability (seeded): the first bad bit ends the
  attempt in an error frame, as an injected corruption does, at that bit.
- Arbitration happens when the bus goes idle, among all frames queued by then, including
  frames queued in the very instant the bus goes idle (the arbitration event runs after every
  other event of that nanosecond). Two nodes sending the same arbitration field: the node
  attached first wins; real buses would collide later in the frame.
"""

from __future__ import annotations

import math
import random
from collections import deque
from collections.abc import Callable
from typing import Any

import can

from board.kernel import PRIO_HW, PRIO_ISR, Event, Kernel, call_in_isr

__all__ = [
    "ERROR_FRAME_BITS",
    "IFS_BITS",
    "CanBus",
    "CanController",
    "arbitration_key",
    "crc15",
    "frame_bits",
    "frame_length_bits",
    "stuffed_length",
]

NS_PER_S = 1_000_000_000
CRC15_POLY = 0x4599
#: Interframe space (intermission) between frames.
IFS_BITS = 3
#: CRC delimiter + ACK slot + ACK delimiter + EOF (not stuffed).
TAIL_BITS = 1 + 1 + 1 + 7
#: Error flag (6) + error delimiter (8).
ERROR_FRAME_BITS = 6 + 8
#: Extra wait of an error-passive transmitter after it transmitted.
SUSPEND_BITS = 8
#: Bus-off recovery: 128 occurrences of 11 recessive bits.
RECOVERY_BITS = 128 * 11
_PRIO_LAST = 1 << 30
_MAX_BITRATE = 1_000_000

TxHandler = Callable[[int, can.Message, bool], Any]
RxHandler = Callable[[int], Any]


# -- frame encoding ----------------------------------------------------------------------------

def crc15(bits: list[int]) -> int:
    """CAN CRC-15 (polynomial 0x4599, init 0) over a bit sequence, MSB first."""
    crc = 0
    for b in bits:
        nxt = b ^ (crc >> 14)
        crc = (crc << 1) & 0x7FFF
        if nxt:
            crc ^= CRC15_POLY
    return crc


def _bits(value: int, n: int) -> list[int]:
    return [(value >> (n - 1 - i)) & 1 for i in range(n)]


def check_frame(msg: can.Message, where: str = "can") -> None:
    """Reject what a classic CAN controller cannot send, saying what and where."""
    if not isinstance(msg, can.Message):
        raise TypeError(f"{where}: expected a can.Message, got {type(msg).__name__}")
    if msg.is_fd or msg.is_error_frame:
        raise ValueError(f"{where}: CAN FD and error frames cannot be sent: {msg}")
    limit = 0x1FFFFFFF if msg.is_extended_id else 0x7FF
    if not 0 <= msg.arbitration_id <= limit:
        kind = "extended" if msg.is_extended_id else "standard"
        raise ValueError(
            f"{where}: {kind} arbitration id 0x{msg.arbitration_id:X} exceeds 0x{limit:X}")
    if not 0 <= msg.dlc <= 8:
        raise ValueError(f"{where}: DLC must be 0..8, got {msg.dlc}")
    if not msg.is_remote_frame and len(msg.data) != msg.dlc:
        raise ValueError(
            f"{where}: DLC {msg.dlc} does not match {len(msg.data)} data bytes")


def frame_bits(msg: can.Message) -> list[int]:
    """Unstuffed bits from SOF to the end of the CRC sequence (0 = dominant)."""
    rtr = int(msg.is_remote_frame)
    if msg.is_extended_id:
        aid = msg.arbitration_id
        bits = [0] + _bits(aid >> 18, 11) + [1, 1] + _bits(aid & 0x3FFFF, 18) + [rtr, 0, 0]
    else:
        bits = [0] + _bits(msg.arbitration_id, 11) + [rtr, 0, 0]
    bits += _bits(msg.dlc, 4)
    if not msg.is_remote_frame:
        for byte in msg.data:
            bits += _bits(byte, 8)
    return bits + _bits(crc15(bits), 15)


def stuffed_length(bits: list[int]) -> int:
    """Length after bit stuffing: a complement bit after every 5 equal bits, the stuff bit
    counting as the first of the next run (including after the last CRC bit)."""
    extra = 0
    run = 0
    last = -1
    for b in bits:
        if b == last:
            run += 1
        else:
            last = b
            run = 1
        if run == 5:
            extra += 1
            last ^= 1
            run = 1
    return len(bits) + extra


_length_cache: dict[tuple, int] = {}


def frame_length_bits(msg: can.Message) -> int:
    """Bits on the wire from SOF to the end of EOF (interframe space not included)."""
    key = (msg.arbitration_id, msg.is_extended_id, msg.is_remote_frame, msg.dlc,
           bytes(msg.data) if not msg.is_remote_frame else b"")
    n = _length_cache.get(key)
    if n is None:
        n = stuffed_length(frame_bits(msg)) + TAIL_BITS
        if len(_length_cache) < 65536:
            _length_cache[key] = n
    return n


def arbitration_key(msg: can.Message) -> int:
    """The arbitration field as an integer: lower wins (dominant 0 first).

    Standard: ID(11), RTR, IDE=0; extended: ID[28:18], SRR=1, IDE=1, ID[17:0], RTR; padded to
    the same 32 bits so that comparing integers compares the bit sequences on the wire.
    """
    aid = msg.arbitration_id
    rtr = int(msg.is_remote_frame)
    if msg.is_extended_id:
        return ((aid >> 18) << 21) | (1 << 20) | (1 << 19) | ((aid & 0x3FFFF) << 1) | rtr
    return (aid << 21) | (rtr << 20)


# -- bus ---------------------------------------------------------------------------------------

class CanBus:
    """The wire: arbitration, frame timing, ACK, error frames; one per physical bus."""

    def __init__(self, kernel: Kernel, name: str, bitrate: int = 1_000_000) -> None:
        if type(bitrate) is not int or not 0 < bitrate <= _MAX_BITRATE:
            raise ValueError(
                f"CanBus {name}: bitrate must be an int in 1..{_MAX_BITRATE} bit/s, "
                f"got {bitrate!r}")
        self.kernel = kernel
        self.name = name
        self.bitrate = bitrate
        self.controllers: list[CanController] = []
        self._idle_ns = 0
        self._busy = False
        self._arb_event: Event | None = None
        self._inject = 0
        self._short = False
        self._ber = 0.0
        self._ber_rng: Any = None
        #: Frames transmitted without error.
        self.frames = 0
        #: Error frames seen on the bus.
        self.error_frames = 0

    def bits_ns(self, t_start_ns: int, nbits: int) -> int:
        """Time ``nbits`` bit times after ``t_start_ns``, floored to a ns from that start."""
        return t_start_ns + (nbits * NS_PER_S) // self.bitrate

    @property
    def idle_ns(self) -> int:
        """When the bus becomes (or became) idle after the current frame and its IFS."""
        return self._idle_ns

    # -- fault hooks ----------------------------------------------------------------------------

    def inject_errors(self, n: int) -> None:
        """Corrupt the next ``n`` transmission attempts: each ends in an error frame, the
        sender counts a transmit error and retransmits, every receiver a receive error."""
        if type(n) is not int or n < 0:
            raise ValueError(f"CanBus {self.name}: inject_errors needs an int >= 0, got {n!r}")
        self._inject += n

    def set_wire_fault(self, short: bool = False, bit_error_rate: float = 0.0,
                       seed: int | str = 0) -> None:
        """Make the wire itself faulty: ``short`` (CAN_H shorted to CAN_L: the bus stays
        recessive, every transmission fails at its SOF) and/or ``bit_error_rate`` (each bit on
        the wire is corrupted with that probability, from a ``random.Random(seed)``). Both off
        heals the wire. Frames already on the wire finish as they started."""
        if not isinstance(bit_error_rate, (int, float)) or not 0.0 <= bit_error_rate <= 1.0:
            raise ValueError(f"CanBus {self.name}: bit_error_rate must be in [0, 1], "
                             f"got {bit_error_rate!r}")
        self._short = bool(short)
        self._ber = float(bit_error_rate)
        self._ber_rng = random.Random(f"{seed}/{self.name}/ber") if self._ber > 0 else None

    @property
    def wire_fault(self) -> tuple[bool, float]:
        """(short, bit_error_rate) of the wire now."""
        return self._short, self._ber

    def force_bus_off(self, controller: CanController) -> None:
        """Put ``controller`` in bus-off now (TEC = 256), as after a burst of errors."""
        if controller.bus is not self:
            raise ValueError(f"CanBus {self.name}: {controller.name} is not on this bus")
        controller.tec = 256
        controller._enter_bus_off(self.kernel.now_ns)

    # -- scheduling -----------------------------------------------------------------------------

    def _request_arbitration(self, t_ns: int | None = None) -> None:
        ev = self._arb_event
        if self._busy or Kernel.pending(ev):
            return
        if t_ns is None:
            t_ns = self.kernel.context_ns
        self._arb_event = self.kernel.call_at(max(t_ns, self._idle_ns), self._arbitrate,
                                              priority=_PRIO_LAST)

    def _arbitrate(self) -> None:
        self._arb_event = None
        now = self.kernel.now_ns
        best = None
        best_key = 0
        later = None
        for ctrl in self.controllers:
            if ctrl._bus_off or not ctrl.enabled:
                continue
            slot = ctrl._next_mailbox()
            if slot is None:
                continue
            if ctrl._earliest_tx_ns > now:
                if later is None or ctrl._earliest_tx_ns < later:
                    later = ctrl._earliest_tx_ns
                continue
            key = arbitration_key(ctrl._mailboxes[slot])
            if best is None or key < best_key:
                best, best_key = (ctrl, slot), key
        if best is None:
            if later is not None:
                self._request_arbitration(later)
            return
        ctrl, slot = best
        msg = ctrl._mailboxes[slot]
        nbits = frame_length_bits(msg)
        ackers = [c for c in self.controllers
                  if c is not ctrl and not c._bus_off and c.enabled]
        err_at = nbits - TAIL_BITS + 2  # after CRC delimiter and ACK slot
        if self._short:
            kind, err_at = "short", 1   # recessive read back at the dominant SOF
        elif self._ber > 0.0 and (bad := self._bit_error(nbits)) is not None:
            kind, err_at = "corrupt", bad
        elif self._inject > 0:
            self._inject -= 1
            kind = "corrupt"
        elif not ackers and not ctrl.loopback:
            kind = "ack"
        else:
            kind = "ok"
        self._busy = True
        if kind == "ok":
            t_end = self.bits_ns(now, nbits)
            self._idle_ns = self.bits_ns(now, nbits + IFS_BITS)
        else:
            t_end = self.bits_ns(now, err_at)
            self._idle_ns = self.bits_ns(now, err_at + ERROR_FRAME_BITS + IFS_BITS)
        self.kernel.call_at(t_end, self._finish, ctrl, slot, msg, kind, priority=PRIO_HW)

    def _bit_error(self, nbits: int) -> int | None:
        """With a bit-error rate: the 1-based bit of this attempt that is corrupted (the error
        frame starts after it), or None if the attempt gets through. Bits after the ACK slot
        (ACK delimiter, EOF) are not drawn."""
        ber = self._ber
        if ber >= 1.0:
            return 1
        u = self._ber_rng.random()  # the first bad bit is geometric: every bit before is good
        k = int(math.log1p(-u) / math.log1p(-ber)) + 1
        return k if k <= nbits - TAIL_BITS + 2 else None

    def _finish(self, ctrl: CanController, slot: int, msg: can.Message, kind: str) -> None:
        now = self.kernel.now_ns
        self._busy = False
        if kind == "ok":
            self.frames += 1
            for c in self.controllers:
                if (c is not ctrl or c.loopback) and not c._bus_off and c.enabled:
                    c._received(now, msg)
            ctrl._tx_done(now, slot, msg, True)
        else:
            self.error_frames += 1
            if kind == "corrupt":
                for c in self.controllers:
                    if c is not ctrl and not c._bus_off and c.enabled:
                        c._receive_error(now)
            ctrl._tx_error(now, slot, msg, ack_error=(kind == "ack"))
        if ctrl.state == "error_passive":
            ctrl._earliest_tx_ns = self.bits_ns(self._idle_ns, SUSPEND_BITS)
        self._request_arbitration(self._idle_ns)

    def __repr__(self) -> str:
        return f"<CanBus {self.name} {self.bitrate} bit/s, {len(self.controllers)} nodes>"


# -- controller --------------------------------------------------------------------------------

class CanController:
    """A bxCAN-like node: 3 TX mailboxes sent lowest identifier first, one RX FIFO.

    ``rx_fifo_depth`` messages fit the FIFO (bxCAN: 3). On overrun (``overruns`` counts them)
    the newest stored message is overwritten (bxCAN RFLM=0), or the incoming one is dropped if
    ``rx_fifo_locked`` (RFLM=1). ``auto_retransmit`` False is bxCAN NART: one attempt, then the
    mailbox is released with ``ok=False``. ``loopback`` (bxCAN LBKM) also receives its own frames
    and ignores a missing ACK. ``enabled=False`` builds it in sleep/initialisation mode (off the
    bus until :meth:`enable`). Interrupts run at ``PRIO_ISR`` with ``kernel.in_isr`` set:
    ``on_receive(handler(t_ns))`` per stored message (FMP), ``on_tx_complete(handler(t_ns, msg,
    ok))`` per released mailbox (RQCP), ``on_error(handler(t_ns, state))`` when the node enters
    error passive or bus-off (bxCAN ERRIE with EPVIE and BOFIE; leaving bus-off raises none).
    """

    N_MAILBOXES = 3

    def __init__(self, bus: CanBus, name: str, rx_fifo_depth: int = 3,
                 rx_fifo_locked: bool = False, auto_retransmit: bool = True,
                 auto_recovery: bool = True, loopback: bool = False,
                 enabled: bool = True) -> None:
        if type(rx_fifo_depth) is not int or rx_fifo_depth <= 0:
            raise ValueError(
                f"CanController {name}: rx_fifo_depth must be a positive int, "
                f"got {rx_fifo_depth!r}")
        self.bus = bus
        self.kernel = bus.kernel
        self.name = name
        self.rx_fifo_depth = rx_fifo_depth
        self.rx_fifo_locked = rx_fifo_locked
        self.auto_retransmit = auto_retransmit
        self.auto_recovery = auto_recovery
        self.loopback = loopback
        self.enabled = bool(enabled)
        self._err_handler: Callable[[int, str], Any] | None = None
        self._mailboxes: list[can.Message | None] = [None] * self.N_MAILBOXES
        self._fifo: deque[can.Message] = deque()
        self._rx_handler: RxHandler | None = None
        self._tx_handler: TxHandler | None = None
        self._bus_off = False
        self._recovery_event: Event | None = None
        self._earliest_tx_ns = 0
        #: Transmit and receive error counters (ISO 11898-1 fault confinement).
        self.tec = 0
        self.rec = 0
        self.overruns = 0
        self.tx_frames = 0
        self.rx_frames = 0
        self.tx_errors = 0
        self.bus_off_count = 0
        bus.controllers.append(self)

    # -- firmware side --------------------------------------------------------------------------

    def send(self, msg: can.Message) -> bool:
        """Load a free TX mailbox; False if all three are busy (the frame is not queued)."""
        check_frame(msg, f"CanController {self.name}.send")
        boxes = self._mailboxes
        for i in range(self.N_MAILBOXES):
            if boxes[i] is None:
                boxes[i] = msg
                if not self._bus_off:
                    self.bus._request_arbitration()
                return True
        return False

    def recv(self) -> can.Message | None:
        """Oldest message in the RX FIFO, or None."""
        return self._fifo.popleft() if self._fifo else None

    @property
    def rx_pending(self) -> int:
        return len(self._fifo)

    @property
    def tx_pending(self) -> int:
        """Mailboxes holding a frame not yet sent."""
        return sum(m is not None for m in self._mailboxes)

    def abort(self) -> None:
        """Empty every TX mailbox (bxCAN ABRQ) without completion interrupts; a frame already
        on the wire still completes."""
        self._mailboxes = [None] * self.N_MAILBOXES

    def on_receive(self, handler: RxHandler | None) -> None:
        """FIFO-message-pending interrupt: ``handler(t_ns)``; the ISR calls :meth:`recv`."""
        self._rx_handler = handler

    def on_tx_complete(self, handler: TxHandler | None) -> None:
        """Request-completed interrupt: ``handler(t_ns, msg, ok)``."""
        self._tx_handler = handler

    def on_error(self, handler: Callable[[int, str], Any] | None) -> None:
        """Error-status interrupt: ``handler(t_ns, state)`` on entering ``error_passive`` or
        ``bus_off``."""
        self._err_handler = handler

    def enable(self) -> None:
        """Leave initialisation mode: take part in the bus from now (bxCAN INRQ cleared)."""
        if not self.enabled:
            self.enabled = True
            if self._next_mailbox() is not None and not self._bus_off:
                self.bus._request_arbitration()

    def disable(self) -> None:
        """Back to initialisation mode: off the bus (a frame on the wire still completes)."""
        self.enabled = False

    def _raise_error(self, t_ns: int, state: str) -> None:
        if self._err_handler is not None:
            self.kernel.call_at(t_ns, call_in_isr, self.kernel, self._err_handler, t_ns, state,
                                priority=PRIO_ISR)

    @property
    def state(self) -> str:
        """'error_active', 'error_passive' or 'bus_off'."""
        if self._bus_off:
            return "bus_off"
        if self.tec > 127 or self.rec > 127:
            return "error_passive"
        return "error_active"

    def recover(self) -> None:
        """Start bus-off recovery (128 x 11 recessive bits) when ``auto_recovery`` is off."""
        if self._bus_off and self._recovery_event is None:
            self._schedule_recovery(self.kernel.context_ns)

    # -- bus side -------------------------------------------------------------------------------

    def _next_mailbox(self) -> int | None:
        best = None
        best_key = 0
        for i, m in enumerate(self._mailboxes):
            if m is not None:
                key = arbitration_key(m)
                if best is None or key < best_key:
                    best, best_key = i, key
        return best

    def _received(self, t_ns: int, msg: can.Message) -> None:
        if self.rec > 127:
            self.rec = 127
        elif self.rec > 0:
            self.rec -= 1
        self.rx_frames += 1
        rx = can.Message(timestamp=t_ns / NS_PER_S, arbitration_id=msg.arbitration_id,
                         is_extended_id=msg.is_extended_id,
                         is_remote_frame=msg.is_remote_frame, dlc=msg.dlc,
                         data=bytes(msg.data) if not msg.is_remote_frame else None,
                         channel=self.name, is_rx=True)
        fifo = self._fifo
        if len(fifo) >= self.rx_fifo_depth:
            self.overruns += 1
            if self.rx_fifo_locked:
                return
            fifo[-1] = rx
            return
        fifo.append(rx)
        if self._rx_handler is not None:
            self.kernel.call_at(t_ns, call_in_isr, self.kernel, self._rx_handler, t_ns,
                                priority=PRIO_ISR)

    def _receive_error(self, t_ns: int) -> None:
        if self.rec < 255:
            self.rec += 1
            if self.rec == 128 and self.tec <= 127:
                self._raise_error(t_ns, "error_passive")

    def _tx_done(self, t_ns: int, slot: int, msg: can.Message, ok: bool) -> None:
        if self._mailboxes[slot] is msg:
            self._mailboxes[slot] = None
        if ok:
            self.tx_frames += 1
            if self.tec > 0 and not self._bus_off:
                self.tec -= 1
        if self._tx_handler is not None:
            self.kernel.call_at(t_ns, call_in_isr, self.kernel, self._tx_handler, t_ns, msg, ok,
                                priority=PRIO_ISR)

    def _tx_error(self, t_ns: int, slot: int, msg: can.Message, ack_error: bool) -> None:
        self.tx_errors += 1
        was = self.state
        if not (ack_error and was == "error_passive"):
            self.tec += 8
        if self.tec > 255:
            self._enter_bus_off(t_ns)
        elif was == "error_active" and self.state == "error_passive":
            self._raise_error(t_ns, "error_passive")
        if not self.auto_retransmit:
            self._tx_done(t_ns, slot, msg, False)

    def _enter_bus_off(self, t_ns: int) -> None:
        if self._bus_off:
            return
        self._bus_off = True
        self.bus_off_count += 1
        self._raise_error(t_ns, "bus_off")
        if self.auto_recovery:
            self._schedule_recovery(t_ns)

    def _schedule_recovery(self, t_ns: int) -> None:
        t = self.bus.bits_ns(max(t_ns, self.kernel.now_ns), RECOVERY_BITS)
        self._recovery_event = self.kernel.call_at(t, self._recovered, priority=PRIO_HW)

    def _recovered(self) -> None:
        self._recovery_event = None
        self._bus_off = False
        self.tec = 0
        self.rec = 0
        if self._next_mailbox() is not None:
            self.bus._request_arbitration(self.kernel.now_ns)

    def __repr__(self) -> str:
        return f"<CanController {self.name} {self.state} TEC={self.tec} REC={self.rec}>"
