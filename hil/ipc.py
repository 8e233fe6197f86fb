"""Lockstep transport between the orchestrator and a board process.

Why this exists
---------------
The orchestrator advances each board once per quantum (default 1 ms of virtual time, down to
tens of microseconds): one "advance to T, here are your inputs" message out, one "here are my
outputs" message back. A ``multiprocessing.Pipe`` round trip costs 40-120 us on the target
machine (a 2-vCPU VM where waking a sleeping process on an idle vCPU costs ~35 us), which alone
would cap a 1 ms quantum below 25x real time. This module gives a duplex channel whose round trip
is 6-10 us when the peer is awake, and that stops burning CPU when the peer stays idle, so that
three processes (orchestrator + two boards) can share two cores.

Measured (``bench/bench_ipc.py``, noisy shared VM): channel round trip 6-10 us vs 38-120 us for a
Pipe; orchestrator + two empty boards 20-33 us per quantum (p10 ~15 us), 29-38 us with 15 us of
world work in the orchestrator between sending and receiving. Pure blocking: 53-140 us per
quantum; spinning without yielding: ~120 us (the spinner starves the third process).

Design
------
* One ``multiprocessing.shared_memory`` segment per channel holds a small control block and two
  byte rings, one per direction. Each ring has a *head* (total bytes ever written, owned by the
  sender) and a *tail* (total bytes ever consumed, owned by the receiver), each in its own cache
  line so that the two processes never write the same line.
* A message is an 8-byte length followed by the payload, padded to 8 bytes. Positions are always
  multiples of 8, so a length word never straddles the end of the ring. Several messages may be
  in flight; a payload larger than the ring is streamed through it in chunks (the sender waits
  for space, the receiver reassembles), so there is no size limit, only a slower path.
* Wake-up is spin-then-block. The receiver first looks at the head word (free when the message
  is already there, which is the common case for the orchestrator collecting replies), then
  spins (calling ``sched_yield`` every few hundred ns so that a process sharing the core runs)
  for up to :attr:`SpinPolicy.max_us`, unless recent waits were longer than that, then blocks
  on a POSIX semaphore (see :class:`SpinPolicy` for why). The sender
  *always* posts the semaphore after publishing the head, so a sleeping receiver cannot miss a
  wake-up; ``sem_post`` with no waiter stays in user space (glibc), so this costs ~0.1 us.
  Tokens left by posts that the receiver did not need are consumed opportunistically
  (one non-blocking acquire per message), keeping the count bounded.
* A blocked call never blocks for more than ``_SLICE_S``: between slices it checks the peer
  (the child's ``Process`` on the parent side, ``os.getppid()`` on the child side) and the
  peer's "closed" flag, so a board killed with SIGKILL surfaces as :class:`PeerDied` in well
  under a second instead of hanging the orchestrator.

Memory ordering: the lock-free fast path (reading the head word, then the payload) relies on
x86-64's total store order: the sender writes the payload before the head and the receiver
reads the head before the payload. On other architectures the receiver always goes through the
semaphore (a full barrier) before trusting the head; that is slower but correct.

Lifetime of the shared memory: the parent creates the segment and unlinks its name as soon as it
has seen the child attach (first message received or :meth:`Channel.wait_attached`), so after
start-up nothing is left in ``/dev/shm`` even if every process is killed. :meth:`Channel.close`
unlinks it if that has not happened yet; unlinking happens exactly once. The multiprocessing
resource tracker covers a parent killed before the child attached.

Usage::

    ctx = multiprocessing.get_context("spawn")
    parent, spec = ChannelPair.create(capacity=1 << 16, ctx=ctx)
    proc = ctx.Process(target=board_main, args=(spec,))   # spec: pass it as a Process argument
    proc.start()
    parent.watch(proc)
    parent.send(b"advance ...")
    reply = parent.recv(timeout_s=5.0)
    ...
    parent.close(); proc.join()

    def board_main(spec):
        with spec.attach() as ch:
            while True:
                try:
                    msg = ch.recv()
                except ChannelClosed:
                    return
                ch.send(outputs)

Start method: the orchestrator should use ``spawn`` (the default of :meth:`ChannelPair.create`).
The parent holds JSBSim, sockets and possibly threads (ground-station bridges); ``fork`` would
copy all of that into the boards, and forking a threaded process is unsafe. Spawn costs a few
hundred milliseconds once per run; the transport's per-quantum speed is the same with both.
"""

from __future__ import annotations

import multiprocessing
import multiprocessing.context
import os
import platform
import secrets
import time
from dataclasses import dataclass
from multiprocessing import shared_memory
from typing import Any, Callable, Protocol

from hil.ipc_spin import SpinPolicy

__all__ = [
    "Channel",
    "ChannelClosed",
    "ChannelError",
    "ChannelPair",
    "ChannelSpec",
    "ChannelTimeout",
    "PeerDied",
    "SpinPolicy",
    "echo_server",
]


class ChannelError(Exception):
    """Base class of the errors raised by a channel."""


class ChannelTimeout(ChannelError, TimeoutError):
    """``recv``/``send`` did not complete within ``timeout_s``; the peer is still alive."""


class PeerDied(ChannelError, ConnectionError):
    """The peer process is gone (crashed, killed) without closing its end."""


class ChannelClosed(ChannelError, EOFError):
    """The peer closed its end cleanly and no message is left to read; or this end is closed."""


# --------------------------------------------------------------------------------------------
# Layout of the shared segment. All offsets are in bytes and multiples of 64 (one cache line) so
# that words written by different processes never share a line.
_LINE = 64
_MAGIC = 0x4C4B535450494831  # "1HIPTSKL": catches attaching to a wrong/foreign segment
_CTL_MAGIC = 0  # u64 word index inside the control line
_CTL_ATTACHED = 1  # set to 1 by the child once attached
_CTL_CLOSED_PARENT = 2  # set to 1 by the parent's close()
_CTL_CLOSED_CHILD = 3  # set to 1 by the child's close()
_RING_HDR = 2 * _LINE  # head line + tail line

# How long one blocking wait lasts before the peer is checked again. Bounds the PeerDied latency
# and costs one futex timeout per slice while idle, i.e. nothing measurable.
_SLICE_S = 0.05

# The lock-free read of head-then-payload is only valid with total store order.
_TSO = platform.machine().lower() in {"x86_64", "amd64", "i386", "i686", "x86"}


_now_ns = time.perf_counter_ns  # CLOCK_MONOTONIC: comparable between processes on Linux
_yield = os.sched_yield


def _pad8(n: int) -> int:
    return (n + 7) & ~7


class _Peer(Protocol):
    def is_alive(self) -> bool: ...


@dataclass(frozen=True)
class ChannelSpec:
    """What a child needs to attach to its end of a channel.

    Picklable, but the semaphores inside can only be pickled while a process is being started:
    pass the spec as an argument of ``Process(...)``, not through a queue or pipe.
    """

    shm_name: str
    capacity: int
    parent_pid: int
    # parent->child data, child->parent data
    sems: tuple[Any, Any]
    spin: SpinPolicy

    def attach(self) -> Channel:
        """Attach in the child. Call once per child."""
        shm = shared_memory.SharedMemory(name=self.shm_name)
        ch = Channel(
            shm,
            self.capacity,
            is_parent=False,
            tx_ring=1,
            rx_ring=0,
            tx_sem=self.sems[1],
            rx_sem=self.sems[0],
            spin=SpinPolicy(**_spin_fields(self.spin)),
        )
        if ch._ctl[_CTL_MAGIC] != _MAGIC:
            ch.close()
            raise ChannelError(f"shared memory {self.shm_name!r} is not a channel")
        parent_pid = self.parent_pid
        ch._peer_alive = lambda: os.getppid() == parent_pid
        ch._ctl[_CTL_ATTACHED] = 1
        return ch


def _spin_fields(p: SpinPolicy) -> dict[str, Any]:
    return {
        "max_us": p.max_us,
        "adaptive": p.adaptive,
        "yield_cpu": p.yield_cpu,
        "alpha": p.alpha,
        "round_checks": p.round_checks,
    }


class ChannelPair:
    """Factory of a parent/child channel."""

    @staticmethod
    def create(
        capacity: int = 1 << 16,
        ctx: multiprocessing.context.BaseContext | None = None,
        spin: SpinPolicy | None = None,
        child_spin: SpinPolicy | None = None,
    ) -> tuple[Channel, ChannelSpec]:
        """Create a channel; return the parent's end and the spec the child attaches with.

        ``capacity`` is the size of each direction's ring in bytes (rounded up to 8). Messages up
        to ``capacity - 8`` bytes go through in one piece; larger ones are streamed.
        ``ctx`` must be the multiprocessing context that will start the child (default: spawn),
        because named semaphores are created differently for fork and spawn.
        ``spin``/``child_spin`` set the receivers' spin policies (default :class:`SpinPolicy`).
        """
        if capacity < 16:
            raise ValueError("capacity must be at least 16 bytes")
        capacity = _pad8(capacity)
        ctx = ctx or multiprocessing.get_context("spawn")
        size = _LINE + 2 * (_RING_HDR + capacity)
        # The creator's pid in the name: whoever finds a segment left behind can tell whether
        # its owner is still alive (another run's live channel) or gone (a leak).
        name = f"hilipc_{os.getpid()}_{secrets.token_hex(6)}"
        shm = shared_memory.SharedMemory(name=name, create=True, size=size)
        sems = (ctx.Semaphore(0), ctx.Semaphore(0))
        # Copies: the adaptive state is per receiver, even if callers reuse one policy object.
        spin = SpinPolicy(**_spin_fields(spin or SpinPolicy()))
        child_spin = SpinPolicy(**_spin_fields(child_spin or SpinPolicy()))
        ch = Channel(
            shm,
            capacity,
            is_parent=True,
            tx_ring=0,
            rx_ring=1,
            tx_sem=sems[0],
            rx_sem=sems[1],
            spin=spin,
        )
        ch._ctl[_CTL_MAGIC] = _MAGIC
        spec = ChannelSpec(name, capacity, os.getpid(), sems, child_spin)
        return ch, spec


class Channel:
    """One end of a duplex message channel (see the module docstring for the design).

    Not thread-safe: one thread sends, one thread receives (possibly the same one).
    """

    def __init__(
        self,
        shm: shared_memory.SharedMemory,
        capacity: int,
        *,
        is_parent: bool,
        tx_ring: int,
        rx_ring: int,
        tx_sem: Any,
        rx_sem: Any,
        spin: SpinPolicy,
    ) -> None:
        self._shm: shared_memory.SharedMemory | None = shm
        self._is_parent = is_parent
        self._cap = capacity
        self._spin = spin
        self._tx_sem = tx_sem
        self._rx_sem = rx_sem
        self._peer_alive: Callable[[], bool] = lambda: True
        self._closed = False
        self._unlinked = is_parent is False  # only the parent unlinks
        buf = shm.buf
        self._ctl = buf[0:_LINE].cast("Q")
        self._my_closed_word = _CTL_CLOSED_PARENT if is_parent else _CTL_CLOSED_CHILD
        self._peer_closed_word = _CTL_CLOSED_CHILD if is_parent else _CTL_CLOSED_PARENT

        # Slicing the mmap object returns bytes in one step, three times cheaper than
        # bytes(memoryview[a:b]); SharedMemory keeps it in ``_mmap`` (CPython 3.8+).
        self._mm = shm._mmap  # type: ignore[attr-defined]
        self._tx_base = _LINE + tx_ring * (_RING_HDR + capacity) + _RING_HDR
        self._rx_base = _LINE + rx_ring * (_RING_HDR + capacity) + _RING_HDR

        def ring(i: int) -> tuple[memoryview, memoryview, memoryview, memoryview]:
            base = _LINE + i * (_RING_HDR + capacity)
            head = buf[base : base + 16].cast("Q")  # [0] head, [1] publish time (ns)
            tail = buf[base + _LINE : base + _LINE + 8].cast("Q")
            data = buf[base + _RING_HDR : base + _RING_HDR + capacity]
            return head, tail, data, data.cast("Q")

        self._tx_head, self._tx_tail, self._tx_data, self._tx_q = ring(tx_ring)
        self._rx_head, self._rx_tail, self._rx_data, self._rx_q = ring(rx_ring)
        # Each side owns one counter per ring; keep a private copy of it.
        self._head = self._tx_head[0]
        self._tail = self._rx_tail[0]

    # ---------------------------------------------------------------- configuration
    def watch(self, peer: _Peer | Callable[[], bool]) -> None:
        """Parent side: tell the channel how to know the child is alive.

        ``peer`` is the child's ``multiprocessing.Process`` (its ``is_alive`` reaps it properly)
        or any callable returning False once the peer is gone.
        """
        is_alive = getattr(peer, "is_alive", None)
        self._peer_alive = is_alive if callable(is_alive) else peer  # type: ignore[assignment]

    @property
    def spin(self) -> SpinPolicy:
        """The receive spin policy of this end (mutable)."""
        return self._spin

    @property
    def capacity(self) -> int:
        return self._cap

    @property
    def closed(self) -> bool:
        return self._closed

    # ---------------------------------------------------------------- sending
    def send(self, payload: bytes | bytearray | memoryview, timeout_s: float | None = None) -> None:
        """Queue one message for the peer.

        Returns as soon as the message is in shared memory, unless the ring is full, in which
        case it waits for the peer to consume (that is also how payloads larger than the ring
        are streamed). Raises :class:`ChannelTimeout`, :class:`PeerDied` or
        :class:`ChannelClosed` (peer closed, or this end closed).
        """
        if self._closed:
            raise ChannelClosed("channel is closed")
        if type(payload) is not bytes:
            payload = memoryview(payload).cast("B")
        n = len(payload)
        head = self._head
        cap = self._cap
        pos = head % cap
        total = 8 + ((n + 7) & ~7)
        if pos + total <= cap and total <= cap - (head - self._tx_tail[0]):
            # Fast path: fits, contiguous. Length and payload first, head last (publication).
            self._tx_q[pos >> 3] = n
            if n:
                start = self._tx_base + pos + 8
                self._mm[start : start + n] = payload
            head += total
            self._head = head
            hv = self._tx_head
            hv[1] = _now_ns()
            hv[0] = head
            self._tx_sem.release()
            return
        self._send_stream(payload, n, timeout_s)

    def _send_stream(
        self, payload: bytes | bytearray | memoryview, n: int, timeout_s: float | None
    ) -> None:
        """Slow path: push the message through the ring as space frees up."""
        mv = memoryview(payload).cast("B")
        cap = self._cap
        data = self._tx_data
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        # The length word goes first, with as much payload as fits; the rest follows in chunks of
        # multiples of 8 bytes so that positions stay aligned.
        sent = -8  # -8: the length word is still to be written
        end_total = _pad8(n)
        backoff = 0.0
        while sent < end_total:
            free = cap - (self._head - self._tx_tail[0])
            if free < 8:
                backoff = self._wait_space(backoff, deadline)
                continue
            backoff = 0.0
            head = self._head
            if sent < 0:
                self._tx_q[(head % cap) >> 3] = n
                head += 8
                free -= 8
                sent = 0
            chunk = min(free & ~7, end_total - sent)
            done = 0
            while done < chunk:
                pos = (head + done) % cap
                k = min(chunk - done, cap - pos)
                lo = sent + done
                hi = min(lo + k, n)
                if hi > lo:
                    data[pos : pos + hi - lo] = mv[lo:hi]
                done += k
            head += chunk
            sent += chunk
            self._head = head
            hv = self._tx_head
            hv[1] = _now_ns()
            hv[0] = head
            self._tx_sem.release()

    def _wait_space(self, backoff: float, deadline: float | None) -> float:
        """Wait (polling with exponential backoff) for the receiver to free ring space.

        Only reached when the ring is full: a slow or busy receiver, or a streamed payload.
        Polling avoids a second semaphore per direction, whose posts would have to be paid on
        every receive for a case the lockstep protocol almost never hits.
        """
        self._check_peer(deadline, "send")
        if backoff == 0.0:
            os.sched_yield()
            return 20e-6
        time.sleep(backoff)
        return min(backoff * 2.0, 1e-3)

    # ---------------------------------------------------------------- receiving
    def recv(self, timeout_s: float | None = None) -> bytes:
        """Return the next message (bytes; a copy, so it stays valid).

        Waits as the spin policy says, then blocks; ``timeout_s=None`` waits forever but still
        raises :class:`PeerDied` if the peer dies and :class:`ChannelClosed` if it closes.
        Messages already queued are delivered before either error.
        """
        if self._closed:
            raise ChannelClosed("channel is closed")
        tail = self._tail
        hv = self._rx_head
        if hv[0] == tail or not _TSO:
            self._wait_data(tail, timeout_s)
        else:
            # Data was already there: consume the token its post left, if it has landed.
            self._rx_sem.acquire(False)
        cap = self._cap
        pos = tail % cap
        n = self._rx_q[pos >> 3]
        total = 8 + ((n + 7) & ~7)
        if pos + total <= cap and hv[0] - tail >= total:
            start = self._rx_base + pos + 8
            out = self._mm[start : start + n]
            tail += total
            self._tail = tail
            self._rx_tail[0] = tail
        else:
            out = self._recv_stream(tail, n, timeout_s)
        if not self._unlinked:
            self._unlink()  # the child has attached: it sent us something
        return out

    def _recv_stream(self, tail: int, n: int, timeout_s: float | None) -> bytes:
        """Slow path: reassemble a message that is (still) larger than what the ring holds."""
        cap = self._cap
        data = self._rx_data
        out = bytearray(n)
        tail += 8
        got = 0
        padded = _pad8(n)
        while got < padded:
            avail = self._rx_head[0] - tail
            if avail == 0:
                self._tail = tail
                self._rx_tail[0] = tail
                self._wait_data(tail, timeout_s)
                continue
            take = min(avail, padded - got)
            done = 0
            while done < take:
                pos = (tail + done) % cap
                k = min(take - done, cap - pos)
                lo = got + done
                hi = min(lo + k, n)
                if hi > lo:
                    out[lo:hi] = data[pos : pos + hi - lo]
                done += k
            got += take
            tail += take
            self._tail = tail
            self._rx_tail[0] = tail
        return bytes(out)

    def _wait_data(self, tail: int, timeout_s: float | None) -> None:
        """Wait until the head moves past ``tail``: spin (adaptive budget), then block."""
        if self._closed:
            raise ChannelClosed("channel is closed")
        head = self._rx_head
        sem = self._rx_sem
        spin = self._spin
        t0 = _now_ns()
        if _TSO:
            budget_ns = spin.budget_s() * 1e9
            if budget_ns > 0.0:
                yield_cpu = spin.yield_cpu
                stop = t0 + budget_ns
                rounds = spin.round_checks
                while True:
                    for _ in range(rounds):
                        if head[0] != tail:
                            sem.acquire(False)
                            spin.observe((head[1] - t0) * 1e-3)
                            return
                    if _now_ns() > stop:
                        break
                    if yield_cpu:
                        _yield()
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        ctl, peer_closed = self._ctl, self._peer_closed_word
        while True:
            # A post always follows a publication, so a token means "look again" (it may be a
            # stale one from a message we already took while spinning: then we just loop).
            slice_s = _SLICE_S
            if deadline is not None:
                slice_s = min(slice_s, max(deadline - time.monotonic(), 0.0))
            got = sem.acquire(True, slice_s)
            if head[0] != tail:
                spin.observe((head[1] - t0) * 1e-3)
                return
            if not got or ctl[peer_closed]:
                self._check_peer(deadline, "recv")

    def _check_peer(self, deadline: float | None, what: str) -> None:
        if self._closed:
            raise ChannelClosed("channel is closed")
        if self._ctl[self._peer_closed_word]:
            raise ChannelClosed(f"{what}: peer closed the channel")
        if not self._peer_alive():
            raise PeerDied(f"{what}: peer process died")
        if deadline is not None and time.monotonic() >= deadline:
            raise ChannelTimeout(f"{what}: no progress within the timeout")

    # ---------------------------------------------------------------- life cycle
    def wait_attached(self, timeout_s: float = 30.0) -> None:
        """Parent side: wait for the child to attach, then drop the segment's name.

        Optional: the first received message does the same. Useful to get the name out of
        ``/dev/shm`` before a long first quantum.
        """
        deadline = time.monotonic() + timeout_s
        while not self._ctl[_CTL_ATTACHED]:
            self._check_peer(deadline, "attach")
            time.sleep(1e-3)
        self._unlink()

    def _unlink(self) -> None:
        if self._unlinked or self._shm is None:
            return
        self._unlinked = True
        try:
            self._shm.unlink()  # also unregisters it from the resource tracker
        except FileNotFoundError:
            pass

    def close(self) -> None:
        """Close this end: tell the peer, release the mapping, unlink (parent, once). Idempotent."""
        if self._closed:
            return
        self._closed = True
        shm = self._shm
        if shm is None:
            return
        try:
            self._ctl[self._my_closed_word] = 1
            # Wake a peer blocked in recv so it notices at once rather than after a slice.
            self._tx_sem.release()
        except (ValueError, OSError):
            pass
        self._unlink()
        for name in ("_ctl", "_tx_head", "_tx_tail", "_tx_q", "_tx_data",
                     "_rx_head", "_rx_tail", "_rx_q", "_rx_data"):
            getattr(self, name).release()
        self._mm = None
        self._shm = None
        # Drop the semaphores so that multiprocessing's finalizers can unlink their names.
        self._tx_sem = self._rx_sem = None
        shm.close()

    def __enter__(self) -> Channel:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:
            pass


def echo_server(spec: ChannelSpec) -> None:
    """Child process body: send every message back until the parent closes. For tests/benches."""
    with spec.attach() as ch:
        while True:
            try:
                msg = ch.recv()
            except (ChannelClosed, PeerDied):
                return
            ch.send(msg)
