"""SPI bus: a controller with several chip-select lines, and the device-model side.

Controller side (what drivers use) is shaped like Linux ``spidev`` and MicroPython
``machine.SPI`` so driver code reads like code that runs on a real bus::

    dev = bus.device("MPU_CS", mode=3, clock_hz=1_000_000)
    who = dev.transfer(b"\\xf5\\x00")[1]           # CS held for the whole transfer
    dev.max_speed_hz = 20_000_000                  # switch to the fast clock, as PX4 does
    with dev.transaction() as tr:                  # CS held across segments
        tr.exchange(b"\\xbb")
        data = tr.exchange(bytes(14))

Device side: subclass :class:`SpiTarget` and override the ``_select`` / ``_exchange`` /
``_deselect`` hooks; the public base methods do the generic part (the clock-limit check).

Timing. Bytes go out at the handle's clock: a transfer of ``n`` bytes lasts
``n * 8 * 10**9 // clock_hz`` ns, added to ``kernel.busy_ns`` (the caller is blocked on the bus,
as with PX4's polled SPI). The device sees the transfer start at ``kernel.context_ns`` taken
before adding, and the deselect at the end. A bus built with ``pclk_hz`` models the STM32 baud
prescaler: the clock actually used is ``pclk_hz // 2**k`` for the smallest k in 1..8 that does
not exceed the requested clock (PX4 asks for 20 MHz on an 84 MHz APB2 and gets 10.5 MHz).

Transfers from interrupt context (``kernel.in_isr``) are allowed: the emulated bus has no
scheduler to block, and the duration still accrues to the ISR's ``busy_ns``. Real PX4 code does
not do this (it schedules a work item); we do not police it.

MISO idles high: with no device on a chip select every byte reads 0xFF.
"""

from __future__ import annotations

import logging
from typing import Final

from mypy_extensions import mypyc_attr

from board.kernel import Kernel

__all__ = ["SpiBus", "SpiBusError", "SpiHandle", "SpiTarget", "SpiTransaction"]

log = logging.getLogger(__name__)

_MODES: Final[tuple[int, ...]] = (0, 1, 2, 3)


@mypyc_attr(native_class=False)
class SpiBusError(RuntimeError):
    """The bus is used in a way the wires cannot do (two chip selects asserted at once)."""


@mypyc_attr(allow_interpreted_subclasses=True)
class SpiTarget:
    """Base class for an SPI device model.

    Subclasses override the hooks; the bus calls the public methods. Attributes a subclass
    sets on the instance, after ``super().__init__()`` (a class attribute of an ordinary
    subclass is not seen by this class when it is compiled: tests/hil/test_native_attributes.py):

    * ``max_clock_hz``: fastest SCK the device accepts (None: no limit). Faster transfers get
      :meth:`_clock_too_fast`'s answer instead of :meth:`_exchange`'s.

    State kept here is readable by tests and status commands: ``selected``, ``mode``,
    ``clock_hz`` (of the current/last selection), ``too_fast_count`` (selections refused for
    speed). The defaults are declared in the class body, so a subclass that forgets
    ``super().__init__()`` still works.
    """

    max_clock_hz: int | None = None
    name: str = ""
    selected: bool = False
    mode: int = 0
    clock_hz: int = 0
    too_fast_count: int = 0
    _too_fast: bool = False

    # -- public side, called by the bus -------------------------------------------------------

    def select(self, t_ns: int, mode: int, clock_hz: int) -> None:
        """CS asserted at ``t_ns`` with SPI ``mode`` and SCK ``clock_hz``."""
        self.selected = True
        self.mode = mode
        self.clock_hz = clock_hz
        limit = self.max_clock_hz
        self._too_fast = limit is not None and clock_hz > limit
        self._select(t_ns, mode, clock_hz)

    def exchange(self, t_ns: int, tx: bytes) -> bytes:
        """Clock ``tx`` out on MOSI from ``t_ns``; returns what the device put on MISO."""
        if self._too_fast:
            return self._clock_too_fast(t_ns, tx)
        return self._exchange(t_ns, tx)

    def deselect(self, t_ns: int) -> None:
        """CS released at ``t_ns``."""
        self.selected = False
        if self._too_fast:
            self._too_fast = False
            self.too_fast_count += 1
            if self.too_fast_count == 1:
                log.warning("SPI device %s: clocked at %d Hz above its maximum %d Hz; "
                            "reads garbage (counted in too_fast_count)",
                            self.name or type(self).__name__, self.clock_hz, self.max_clock_hz)
        self._deselect(t_ns)

    # -- hooks for subclasses -----------------------------------------------------------------

    def _select(self, t_ns: int, mode: int, clock_hz: int) -> None:
        """CS fell: reset the transaction state (a new command byte follows)."""

    def _exchange(self, t_ns: int, tx: bytes) -> bytes:
        """Full duplex: return exactly ``len(tx)`` bytes. Called one or more times per
        selection; later calls continue the same transaction."""
        return b"\xff" * len(tx)

    def _deselect(self, t_ns: int) -> None:
        """CS rose: commit writes, end bursts."""

    def _clock_too_fast(self, t_ns: int, tx: bytes) -> bytes:
        """What the device answers when clocked above ``max_clock_hz``.

        Default: 0xFF on MISO and the transfer is ignored (a device that cannot follow the
        clock does not decode the command). Override for a device that answers garbage
        differently; the bus counts and logs the refusal once per selection either way.
        """
        return b"\xff" * len(tx)


class _Cs:
    """One chip-select line and what hangs on it."""

    __slots__ = ("name", "target")

    def __init__(self, name: str) -> None:
        self.name = name
        self.target: SpiTarget | None = None


class SpiBus:
    """One SPI controller (e.g. SPI1 of the FMU) and its chip-select lines."""

    def __init__(self, kernel: Kernel, name: str, cs_names: tuple[str, ...] | None = None,
                 pclk_hz: int | None = None) -> None:
        """``cs_names`` (optional) fixes the set of chip selects so a typo raises;
        ``pclk_hz`` (optional) makes clocks snap to the STM32 prescaler steps."""
        if pclk_hz is not None and (type(pclk_hz) is not int or pclk_hz <= 0):
            raise ValueError(f"SPI bus {name}: pclk_hz must be a positive int, got {pclk_hz!r}")
        self.kernel = kernel
        self.name = name
        self.pclk_hz = pclk_hz
        self._fixed = cs_names is not None
        self._cs: dict[str, _Cs] = {}
        for cs in cs_names or ():
            self._cs[cs] = _Cs(cs)
        #: The handle whose chip select is asserted (None: bus idle).
        self.owner: SpiHandle | None = None
        #: Transfers (or transaction segments) clocked so far, and bytes moved.
        self.transfers = 0
        self.bytes = 0
        #: MISO shorted (fault injection): every byte any device sends reads this value
        #: (b"\xff" stuck high, b"\x00" stuck low); None for a healthy line. The devices
        #: still receive MOSI.
        self.miso_stuck: bytes | None = None

    def set_miso_stuck(self, level: int | None) -> None:
        """Short MISO to VDD (``1``: every byte reads 0xFF) or to ground (``0``: 0x00), or
        heal it (None): a solder bridge, a chip that latched up driving its output, a cracked
        trace floating high through the pull-up."""
        if level not in (None, 0, 1):
            raise ValueError(f"SPI bus {self.name}: MISO stuck level must be 0, 1 or None, "
                             f"got {level!r}")
        self.miso_stuck = None if level is None else (b"\xff" if level else b"\x00")

    def _line(self, cs_name: str, where: str) -> _Cs:
        line = self._cs.get(cs_name)
        if line is None:
            if self._fixed or not isinstance(cs_name, str) or not cs_name:
                raise ValueError(f"SPI bus {self.name}.{where}: unknown chip select "
                                 f"{cs_name!r} (known: {', '.join(self._cs) or 'none'})")
            line = self._cs[cs_name] = _Cs(cs_name)
        return line

    def attach(self, cs_name: str, target: SpiTarget) -> None:
        """Wire ``target`` to chip select ``cs_name`` (one device per chip select)."""
        if not isinstance(target, SpiTarget):
            raise TypeError(f"SPI bus {self.name}.attach({cs_name!r}): {target!r} is not an "
                             f"SpiTarget")
        line = self._line(cs_name, "attach")
        if line.target is not None:
            raise ValueError(f"SPI bus {self.name}.attach: chip select {cs_name!r} already has "
                             f"{line.target!r}")
        line.target = target
        if not target.name:
            target.name = f"{self.name}.{cs_name}"

    def detach(self, cs_name: str) -> SpiTarget | None:
        """Remove the device on ``cs_name`` (a fault: the chip is gone); returns it."""
        line = self._line(cs_name, "detach")
        target, line.target = line.target, None
        return target

    def target(self, cs_name: str) -> SpiTarget | None:
        """The device attached to ``cs_name``, if any."""
        return self._line(cs_name, "target").target

    def device(self, cs_name: str, mode: int = 3, clock_hz: int = 1_000_000) -> SpiHandle:
        """A driver's handle on chip select ``cs_name`` (like opening /dev/spidevB.C)."""
        return SpiHandle(self, self._line(cs_name, "device"), mode, clock_hz)

    def effective_clock_hz(self, clock_hz: int) -> int:
        """The SCK the controller produces for a requested ``clock_hz``."""
        pclk = self.pclk_hz
        if pclk is None:
            return clock_hz
        for k in range(1, 9):
            if pclk >> k <= clock_hz:
                return pclk >> k
        return pclk >> 8

    def __repr__(self) -> str:
        return f"<SpiBus {self.name} cs={list(self._cs)}>"


class SpiHandle:
    """Controller-side handle on one chip select, with its own mode and clock."""

    __slots__ = ("_kernel", "_line", "_mode", "_requested_hz", "bus", "clock_hz")

    def __init__(self, bus: SpiBus, line: _Cs, mode: int, clock_hz: int) -> None:
        self.bus = bus
        self._line = line
        self._kernel = bus.kernel
        self.mode = mode
        self.max_speed_hz = clock_hz

    # -- configuration (spidev names) ---------------------------------------------------------

    @property
    def cs_name(self) -> str:
        return self._line.name

    @property
    def mode(self) -> int:
        """SPI mode 0..3 (CPOL << 1 | CPHA), as spidev."""
        return self._mode

    @mode.setter
    def mode(self, mode: int) -> None:
        if mode not in _MODES or type(mode) is not int:
            raise ValueError(f"SPI {self.bus.name}.{self._line.name}: mode must be 0..3, "
                             f"got {mode!r}")
        self._mode = mode

    @property
    def max_speed_hz(self) -> int:
        """Requested SCK in Hz (spidev name); :attr:`clock_hz` is what the bus produces."""
        return self._requested_hz

    @max_speed_hz.setter
    def max_speed_hz(self, clock_hz: int) -> None:
        if type(clock_hz) is not int or clock_hz <= 0:
            raise ValueError(f"SPI {self.bus.name}.{self._line.name}: clock must be a positive "
                             f"int in Hz, got {clock_hz!r}")
        self._requested_hz = clock_hz
        self.clock_hz = self.bus.effective_clock_hz(clock_hz)

    def duration_ns(self, n_bytes: int) -> int:
        """How long ``n_bytes`` take on the wire at the current clock."""
        return n_bytes * 8_000_000_000 // self.clock_hz

    # -- one-shot transfers (CS asserted for the whole call) ----------------------------------

    def transfer(self, tx: bytes) -> bytes:
        """Full-duplex transfer with CS asserted around it; returns the bytes read."""
        bus = self.bus
        if bus.owner is not None:
            self._busy("transfer")
        if type(tx) is not bytes:
            tx = self._as_bytes(tx, "transfer")
        kernel = self._kernel
        n = len(tx)
        t = kernel.now_ns + kernel.busy_ns
        dur = n * 8_000_000_000 // self.clock_hz
        kernel.busy_ns += dur
        bus.transfers += 1
        bus.bytes += n
        target = self._line.target
        if target is None:
            return b"\xff" * n if bus.miso_stuck is None else bus.miso_stuck * n
        target.select(t, self._mode, self.clock_hz)
        rx = target.exchange(t, tx)
        target.deselect(t + dur)
        if len(rx) != n:
            self._bad_reply(target, n, rx)
        if bus.miso_stuck is not None:
            return bus.miso_stuck * n
        return bytes(rx) if type(rx) is not bytes else rx

    def write_readinto(self, tx: bytes, rx_buf: bytearray | memoryview) -> None:
        """MicroPython ``SPI.write_readinto``: ``tx`` and ``rx_buf`` must have equal length."""
        if len(tx) != len(rx_buf):
            raise ValueError(f"SPI {self.bus.name}.{self._line.name}.write_readinto: "
                             f"buffers differ in length ({len(tx)} vs {len(rx_buf)})")
        rx_buf[:] = self.transfer(tx)

    def write(self, tx: bytes) -> None:
        """MicroPython ``SPI.write``: send, discard what comes back."""
        self.transfer(tx)

    def read(self, n: int, write: int = 0x00) -> bytes:
        """MicroPython ``SPI.read``: clock ``n`` bytes of ``write`` out, return what came in."""
        if type(n) is not int or n < 0:
            raise ValueError(f"SPI {self.bus.name}.{self._line.name}.read: bad length {n!r}")
        return self.transfer(bytes((write,)) * n)

    def readinto(self, buf: bytearray | memoryview, write: int = 0x00) -> None:
        """MicroPython ``SPI.readinto``."""
        buf[:] = self.read(len(buf), write)

    def xfer(self, values: list[int]) -> list[int]:
        """spidev ``xfer``/``xfer2``: a list of ints in, a list of ints out (CS held)."""
        return list(self.transfer(self._as_bytes(values, "xfer")))

    def xfer2(self, values: list[int]) -> list[int]:
        """spidev ``xfer2``: the same as :meth:`xfer` here (CS is held for the whole list)."""
        return self.xfer(values)

    def writebytes(self, values: list[int]) -> None:
        """spidev ``writebytes``."""
        self.transfer(self._as_bytes(values, "writebytes"))

    def readbytes(self, n: int) -> list[int]:
        """spidev ``readbytes`` (clocks out zeros)."""
        return list(self.read(n))

    # -- multi-part transactions ---------------------------------------------------------------

    def select(self) -> None:
        """Assert CS and keep it asserted over :meth:`exchange` calls until :meth:`deselect`."""
        bus = self.bus
        if bus.owner is not None:
            self._busy("select")
        bus.owner = self
        target = self._line.target
        if target is not None:
            target.select(self._kernel.context_ns, self._mode, self.clock_hz)

    def exchange(self, tx: bytes) -> bytes:
        """One segment of a transaction opened with :meth:`select`."""
        bus = self.bus
        if bus.owner is not self:
            raise SpiBusError(f"SPI {bus.name}.{self._line.name}: exchange() without select()")
        if type(tx) is not bytes:
            tx = self._as_bytes(tx, "exchange")
        kernel = self._kernel
        n = len(tx)
        t = kernel.now_ns + kernel.busy_ns
        kernel.busy_ns += n * 8_000_000_000 // self.clock_hz
        bus.transfers += 1
        bus.bytes += n
        target = self._line.target
        if target is None:
            return b"\xff" * n if bus.miso_stuck is None else bus.miso_stuck * n
        rx = target.exchange(t, tx)
        if len(rx) != n:
            self._bad_reply(target, n, rx)
        if bus.miso_stuck is not None:
            return bus.miso_stuck * n
        return bytes(rx) if type(rx) is not bytes else rx

    def deselect(self) -> None:
        """Release CS (ends the transaction)."""
        bus = self.bus
        if bus.owner is not self:
            raise SpiBusError(f"SPI {bus.name}.{self._line.name}: deselect() without select()")
        bus.owner = None
        target = self._line.target
        if target is not None:
            target.deselect(self._kernel.context_ns)

    def transaction(self) -> SpiTransaction:
        """Context manager: ``with dev.transaction() as tr: tr.exchange(...)``."""
        return SpiTransaction(self)

    # -- errors ----------------------------------------------------------------------------------

    def _busy(self, where: str) -> None:
        owner = self.bus.owner
        raise SpiBusError(
            f"SPI {self.bus.name}.{self._line.name}.{where}: chip select "
            f"{owner._line.name if owner else '?'} is still asserted (missing deselect or bus "
            f"lock)")

    def _as_bytes(self, data: object, where: str) -> bytes:
        try:
            return bytes(data)  # type: ignore[call-overload]
        except (TypeError, ValueError) as exc:
            raise ValueError(f"SPI {self.bus.name}.{self._line.name}.{where}: cannot send "
                             f"{data!r}: {exc}") from None

    def _bad_reply(self, target: SpiTarget, n: int, rx: object) -> None:
        raise ValueError(f"SPI {self.bus.name}.{self._line.name}: device model "
                         f"{type(target).__name__} answered {n} bytes sent with "
                         f"{len(rx)} bytes (must be equal)")  # type: ignore[arg-type]

    def __repr__(self) -> str:
        return (f"<SpiHandle {self.bus.name}.{self._line.name} mode={self._mode} "
                f"clock={self.clock_hz} Hz>")


class SpiTransaction:
    """CS held for the duration of a ``with`` block; ``exchange`` segments inside it."""

    __slots__ = ("handle",)

    def __init__(self, handle: SpiHandle) -> None:
        self.handle = handle

    def __enter__(self) -> SpiHandle:
        self.handle.select()
        return self.handle

    def __exit__(self, *exc: object) -> None:
        self.handle.deselect()
