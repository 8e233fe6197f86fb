"""FMU side of the PX4IO serial link: one transaction at a time, reply or 10 ms timeout, 3 tries.

The E14 driver is a task that blocks on a semaphore posted by the USART6 interrupt. Here the
task is a generator run by :class:`IoThread`; it yields :class:`ReplyWait` after writing a
request, and the UART's IDLE interrupt (end of the reply burst) or an HRT timeout resumes it.
So a transaction costs what it costs on the wire (request and reply at 1.5 Mbit/s, the IO's
turnaround, one character of idle line) and nothing is polled.

Error handling follows io-and-rc.md §1.7: timeouts, UART errors (a break from the IO), short
replies, CRC failures and CORRUPT replies are retried, up to 3 attempts in all; an ERROR reply
fails the call at once; a read answered with another register count fails with "EIO". The
counters keep PX4's names (``io_txns``, ``io_retries``, ...).
"""

from __future__ import annotations

from collections.abc import Callable, Generator, Sequence
from typing import TYPE_CHECKING, Any, Final

from board.kernel import NS_PER_US, PRIO_THREAD, KernelError
from board.uart import Uart
from firmware.platform.task import Poll, PollWaiter, Sleep
from ioproc.protocol import (
    FMU_ATTEMPTS,
    FMU_MAX_REGS_PER_CALL,
    FMU_REPLY_TIMEOUT_US,
    LAYOUT,
    PKT_COUNT_MASK,
    CrcError,
    ProtocolError,
    Reply,
    ReplyCode,
    decode_reply,
    encode_read,
    encode_write,
)

if TYPE_CHECKING:
    from firmware.platform import Platform
    from firmware.platform.hrt import HrtCall
    from firmware.platform.perf import PerfCounter

__all__ = ["IO_LOST_CALLS", "IoLink", "IoThread", "ReplyWait", "Txn"]

#: Consecutive calls that got no usable reply (after all their attempts) before the driver
#: reports the IO as lost. [model] E14 has no such report; 10 calls are 0.3 s of silence.
IO_LOST_CALLS: Final = 10

#: What a transaction generator yields and gets back.
Txn = Generator[Any, Any, Any]

_IDLE: Final = "idle"
_TIMEOUT: Final = "timeout"


class ReplyWait:
    """Yielded by a thread to wait for the IO's reply (UART IDLE) or ``timeout_us``."""

    __slots__ = ("timeout_us",)

    def __init__(self, timeout_us: int) -> None:
        self.timeout_us = timeout_us


class IoThread:
    """The px4io task: a generator that waits on uORB (poll), time (sleep) or the IO's reply.

    :class:`firmware.platform.task.Task` knows poll and sleep; the driver also has to wait for
    an interrupt of its UART, which is what the E14 task does on its semaphore. Every wait
    carries a token so a late wake-up (a reply after its timeout) cannot resume the wrong wait.
    """

    def __init__(self, platform: Platform, uart: Uart, name: str,
                 main: Callable[[IoThread], Txn], priority: int) -> None:
        self.platform = platform
        self.uart = uart
        self.name = name
        self._main = main
        self._kprio = PRIO_THREAD - priority
        self._gen: Txn | None = None
        self._token = 0
        self._waiting_reply = False
        self._timer: HrtCall | None = None
        self._poller: PollWaiter | None = None
        self._event: list | None = None
        self.running = False
        self.should_exit = False

    def start(self) -> None:
        self._gen = self._main(self)
        self.running = True
        self.uart.on_idle(self._on_idle)
        k = self.platform.kernel
        self._event = k.call_at(k.now_ns + k.busy_ns, self._resume, self._token, None,
                                priority=self._kprio)

    def stop(self) -> None:
        """End the thread now (from outside it): pending waits are cancelled."""
        self.should_exit = True
        self.running = False
        self._cancel_waits()
        self.uart.on_idle(None)
        gen, self._gen = self._gen, None
        if gen is not None:
            gen.close()

    def _cancel_waits(self) -> None:
        self._token += 1
        self._waiting_reply = False
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        if self._poller is not None:
            self._poller.cancel()
            self._poller = None
        if self._event is not None:
            self.platform.kernel.cancel(self._event)
            self._event = None

    # -- wake-ups ---------------------------------------------------------------------------

    def _on_idle(self, t_ns: int) -> None:
        """USART6 IDLE interrupt: the reply burst has ended; wake the task if it waits."""
        if self._waiting_reply:
            self._wake(_IDLE)

    def _on_timeout(self) -> None:
        # The one reply timer is re-armed by every ReplyWait (see _step), so when it fires
        # while a reply is awaited, its deadline is that wait's.
        if self._waiting_reply:
            self._wake(_TIMEOUT)

    def _wake(self, value: Any) -> None:
        # The reply timer is left pending: the next transaction moves its deadline (no heap
        # entry per transaction); firing with no reply awaited does nothing.
        self._waiting_reply = False
        k = self.platform.kernel
        self._event = k.post(k.now_ns, self._kprio, self._resume, (self._token, value))

    def _poll_done(self, n: int) -> None:
        self._poller = None
        self._step(n)

    def _resume(self, token: int, value: Any) -> None:
        self._event = None
        if token == self._token:
            self._step(value)

    def _step(self, value: Any) -> None:
        gen = self._gen
        if gen is None or not self.running:
            return
        k = self.platform.kernel
        self._token += 1
        try:
            req = gen.send(value)
        except StopIteration:
            self.running = False
            self._gen = None
            self.uart.on_idle(None)
            return
        except KernelError:
            raise
        except Exception as exc:
            self.running = False
            raise KernelError(f"{k.name}: task {self.name} raised at t={k.now_ns} ns: "
                              f"{type(exc).__name__}: {exc}", k.now_ns, self.name) from exc
        token = self._token
        if isinstance(req, ReplyWait):
            self._waiting_reply = True
            timer = self._timer
            if timer is None:
                self._timer = self.platform.hrt.call_after(req.timeout_us, self._on_timeout)
            else:
                timer.rearm_after(req.timeout_us)
        elif isinstance(req, Poll):
            self._poller = PollWaiter(self.platform, req.subs, req.timeout_us, self._poll_done,
                                      self._kprio)
        elif isinstance(req, Sleep):
            self._event = k.call_at(k.now_ns + k.busy_ns + req.us * NS_PER_US, self._resume,
                                    token, None, priority=self._kprio)
        else:
            self.running = False
            raise KernelError(f"{k.name}: task {self.name} yielded {req!r}", k.now_ns, self.name)


class IoLink:
    """Register reads and writes over the UART, with E14's retry rules and perf counters.

    ``perf_alloc(kind, name)`` makes the counters (the module's, so ``stop`` frees them);
    ``log(severity_name, text)`` reports a lost or recovered link.
    """

    def __init__(self, uart: Uart, perf_alloc: Callable[[str, str], PerfCounter],
                 log: Callable[[str, str], None]) -> None:
        self.uart = uart
        self.log = log
        self.pc_txns = perf_alloc("elapsed", "io_txns")
        self.pc_retries = perf_alloc("count", "io_retries")
        self.pc_timeouts = perf_alloc("count", "io_timeouts")
        self.pc_crcerrs = perf_alloc("count", "io_crcerrs")
        self.pc_protoerrs = perf_alloc("count", "io_protoerrs")
        self.pc_uarterrs = perf_alloc("count", "io_uarterrs")
        self.pc_badidle = perf_alloc("count", "io_badidle")
        self.pc_errors = perf_alloc("count", "io_errors")
        #: attempts that produced no usable reply (px4io_status.link_errors)
        self.failed_attempts = 0
        #: calls that failed after every attempt, in a row (0 after any reply)
        self.consecutive_failures = 0
        self.lost = False
        self.lost_count = 0
        self.last_error = ""
        self.max_regs = FMU_MAX_REGS_PER_CALL

    # -- the register helpers (io_reg_get / io_reg_set / io_reg_modify) ---------------------

    def read(self, page: int, offset: int, count: int) -> Txn:
        """``count`` registers from (page, offset), or None; use as ``yield from``."""
        if not 0 < count <= self.max_regs:
            raise ValueError(f"px4io read of {count} registers (1..{self.max_regs})")
        reply = yield from self.transfer(encode_read(page, offset, count), page, offset, count)
        return None if reply is None else list(reply.values)

    def write(self, page: int, offset: int, values: Sequence[int]) -> Txn:
        """Write registers; True when the IO acknowledged with SUCCESS."""
        if not 0 < len(values) <= self.max_regs:
            raise ValueError(f"px4io write of {len(values)} registers (1..{self.max_regs})")
        reply = yield from self.transfer(encode_write(page, offset, values), page, offset, None)
        return reply is not None

    def modify(self, page: int, offset: int, clear: int, set_bits: int) -> Txn:
        """Read one register, clear then set bits, write it back (two transactions)."""
        regs = yield from self.read(page, offset, 1)
        if regs is None:
            return None
        value = (regs[0] & ~clear | set_bits) & 0xFFFF
        ok = yield from self.write(page, offset, [value])
        return value if ok else None

    # -- one call: up to FMU_ATTEMPTS attempts ---------------------------------------------

    def transfer(self, request: bytes, page: int, offset: int, read_count: int | None) -> Txn:
        """Send ``request`` until a usable reply comes back; the Reply, or None."""
        uart = self.uart
        for attempt in range(FMU_ATTEMPTS):
            if attempt:
                self.pc_retries.count()
            uart.reset_input_buffer()  # the DMA is re-armed per attempt: stale bytes are gone
            uart.take_errors()
            self.pc_txns.begin()
            uart.write(request)
            why = yield ReplyWait(FMU_REPLY_TIMEOUT_US)
            if why == _TIMEOUT:
                self.pc_txns.cancel()
                self.pc_timeouts.count()
                self._attempt_failed(f"no reply within {FMU_REPLY_TIMEOUT_US // 1000} ms")
                continue
            self.pc_txns.end()
            reply = self._check(uart.read(), uart.take_errors(), page, offset)
            if reply is None:
                continue
            self._link_ok()
            if reply.code is ReplyCode.ERROR:
                self.pc_errors.count()
                self.last_error = f"IO refused the access to page {page} offset {offset}"
                return None
            if read_count is not None and len(reply.values) != read_count:
                self.pc_protoerrs.count()
                self.last_error = (f"read of page {page} offset {offset}: {len(reply.values)} "
                                   f"registers returned, {read_count} asked (EIO)")
                return None
            return reply
        self._call_failed()
        return None

    def _check(self, data: bytes, errors: int, page: int, offset: int) -> Reply | None:
        """Decode one received burst; count and return None if it is unusable (retry)."""
        if errors:
            self.pc_uarterrs.count()
            self._attempt_failed(f"UART error 0x{errors:02X} in the reply (IO break?)")
            return None
        if len(data) < LAYOUT.header_size or len(data) < LAYOUT.size(data[0] & PKT_COUNT_MASK):
            self.pc_badidle.count()
            self._attempt_failed(f"short reply of {len(data)} bytes")
            return None
        try:
            reply = decode_reply(data)
        except CrcError as exc:
            self.pc_crcerrs.count()
            self._attempt_failed(str(exc))
            return None
        except ProtocolError as exc2:
            self.pc_protoerrs.count()
            self._attempt_failed(str(exc2))
            return None
        if reply.code is ReplyCode.CORRUPT:
            self.pc_protoerrs.count()
            self._attempt_failed("IO received a corrupt request")
            return None
        if (reply.page, reply.offset) != (page, offset):
            # [model] E14 does not compare the echo; a late reply to an earlier attempt would
            # otherwise be taken for this one.
            self.pc_protoerrs.count()
            self._attempt_failed(f"reply for page {reply.page} offset {reply.offset}, "
                                 f"expected {page}/{offset}")
            return None
        return reply

    def _attempt_failed(self, why: str) -> None:
        self.failed_attempts += 1
        self.last_error = why

    def _call_failed(self) -> None:
        self.consecutive_failures += 1
        if not self.lost and self.consecutive_failures >= IO_LOST_CALLS:
            self.lost = True
            self.lost_count += 1
            self.log("error", f"IO lost: no usable reply to {self.consecutive_failures} "
                              f"transactions in a row ({self.last_error}); still trying")

    def _link_ok(self) -> None:
        if self.lost:
            self.lost = False
            self.log("info", f"IO link restored after {self.consecutive_failures} failed "
                             f"calls")
        self.consecutive_failures = 0
