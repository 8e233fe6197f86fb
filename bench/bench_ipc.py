"""Benchmarks of the orchestrator <-> board transport (hil.ipc).

Run as a script (``.venv/bin/python bench/bench_ipc.py [--quick] [--all]``) to print the three
headline figures (plus the lockstep loop with ~15 us of parent work per quantum, the JSBSim step);
``--all`` adds the experiments that chose the default spin policy: an eventfd wake-up round trip,
and pure blocking vs fixed spins with/without ``sched_yield`` vs the adaptive default, each with
and without parent work, on a machine where three processes share two cores.

Figures on the 2-vCPU Firecracker VM (noisy: other agents were running at the same time):
pipe round trip 38-120 us; channel round trip 6-10 us; lockstep with two empty boards
20-33 us/quantum (p10 ~15 us), 29-38 us/quantum with 15 us of parent work. Pure blocking on the
semaphores: 18-63 us round trip, 53-140 us/quantum (waking an idle vCPU costs ~35 us here:
an eventfd wake-up round trip takes 73 us on an idle machine, 9 us when other load keeps the
vCPUs awake). Spinning without yielding: 121 us/quantum (a spinner starves the
third process). Spin + sched_yield: 20-35 us/quantum.

Every figure is the median of ``runs`` timed runs, each of ``n`` round trips/quanta, after a
warm-up, with the child processes started once (start-up cost is not measured).
"""

from __future__ import annotations

import multiprocessing
import multiprocessing.connection
import os
import statistics
import struct
import sys
import time
from pathlib import Path
from typing import Callable

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from hil.ipc import Channel, ChannelClosed, ChannelPair, ChannelSpec, PeerDied, SpinPolicy

N = 20000
RUNS = 5
WARMUP = 2000
_ADVANCE = struct.Struct("<q")


def _median_us(run: Callable[[int], float], n: int, runs: int) -> float:
    """Median over ``runs`` of (seconds for ``n`` iterations) / n, in microseconds."""
    run(min(WARMUP, n))
    return statistics.median(run(n) / n * 1e6 for _ in range(runs))


def _busy(us: float) -> None:
    """Burn CPU for ``us`` microseconds (stands in for the world step)."""
    if us <= 0:
        return
    pc = time.perf_counter
    end = pc() + us * 1e-6
    while pc() < end:
        pass


# ------------------------------------------------------------------------------ children
def _pipe_echo(conn: multiprocessing.connection.Connection) -> None:
    try:
        while True:
            conn.send_bytes(conn.recv_bytes())
    except EOFError:
        pass


def _eventfd_echo(efd_in: int, efd_out: int) -> None:
    while True:
        v = os.eventfd_read(efd_in)
        if v > 1:  # the parent writes 2 to stop
            return
        os.eventfd_write(efd_out, 1)


def _empty_board(spec: ChannelSpec, cpu: int | None = None) -> None:
    """A board that does nothing: ``advance(T, inputs) -> b""``."""
    if cpu is not None:
        os.sched_setaffinity(0, {cpu})
    with spec.attach() as ch:
        while True:
            try:
                msg = ch.recv()
            except (ChannelClosed, PeerDied):
                return
            _t = _ADVANCE.unpack_from(msg)[0]
            ch.send(b"")


def _start(ctx: multiprocessing.context.BaseContext, target: Callable[..., None], *args: object):
    p = ctx.Process(target=target, args=args, daemon=True)
    p.start()
    return p


# ------------------------------------------------------------------------------ benches
def bench_pipe_roundtrip_us(n: int = N, runs: int = RUNS, payload: bytes = b"x" * 64) -> float:
    """Round trip over a plain ``multiprocessing.Pipe`` to an echoing child (the baseline)."""
    ctx = multiprocessing.get_context("spawn")
    a, b = ctx.Pipe()
    p = _start(ctx, _pipe_echo, b)
    b.close()

    def run(k: int) -> float:
        t0 = time.perf_counter()
        for _ in range(k):
            a.send_bytes(payload)
            a.recv_bytes()
        return time.perf_counter() - t0

    try:
        return _median_us(run, n, runs)
    finally:
        a.close()
        p.join(5)


def bench_eventfd_roundtrip_us(n: int = N, runs: int = RUNS) -> float:
    """Round trip of a bare wake-up over two eventfds (blocking reads; no payload). Fork only."""
    ctx = multiprocessing.get_context("fork")
    e1, e2 = os.eventfd(0), os.eventfd(0)
    p = _start(ctx, _eventfd_echo, e1, e2)

    def run(k: int) -> float:
        t0 = time.perf_counter()
        for _ in range(k):
            os.eventfd_write(e1, 1)
            os.eventfd_read(e2)
        return time.perf_counter() - t0

    try:
        return _median_us(run, n, runs)
    finally:
        os.eventfd_write(e1, 2)
        p.join(5)
        os.close(e1)
        os.close(e2)


def bench_channel_roundtrip_us(
    n: int = N,
    runs: int = RUNS,
    payload: bytes = b"x" * 64,
    spin: SpinPolicy | None = None,
    child_spin: SpinPolicy | None = None,
    start_method: str = "spawn",
) -> float:
    """Round trip over a :mod:`hil.ipc` channel to a child running :func:`echo_server`."""
    from hil.ipc import echo_server

    ctx = multiprocessing.get_context(start_method)
    ch, spec = ChannelPair.create(1 << 16, ctx=ctx, spin=spin, child_spin=child_spin)
    p = _start(ctx, echo_server, spec)
    ch.watch(p)
    ch.wait_attached()

    def run(k: int) -> float:
        send, recv = ch.send, ch.recv
        t0 = time.perf_counter()
        for _ in range(k):
            send(payload)
            recv()
        return time.perf_counter() - t0

    try:
        return _median_us(run, n, runs)
    finally:
        ch.close()
        p.join(5)


def bench_lockstep_overhead_us_per_quantum(
    n: int = N,
    runs: int = RUNS,
    parent_work_us: float = 0.0,
    spin: SpinPolicy | None = None,
    child_spin: SpinPolicy | None = None,
    start_method: str = "spawn",
    pin: bool = False,
) -> float:
    """Orchestrator-shaped loop with two empty boards; microseconds per quantum.

    Per quantum: send "advance to T" to both boards, do ``parent_work_us`` of CPU work (the
    world step), then collect both (empty) replies. With ``parent_work_us > 0`` the figure
    includes that work; subtract it to get the transport's share. ``pin`` puts the parent on
    CPU 0 and both boards on CPU 1 (an experiment; the parent's affinity is restored).
    """
    saved_affinity = os.sched_getaffinity(0)
    if pin:
        os.sched_setaffinity(0, {0})
    ctx = multiprocessing.get_context(start_method)
    ends: list[Channel] = []
    procs = []
    for _ in range(2):
        ch, spec = ChannelPair.create(1 << 16, ctx=ctx, spin=spin, child_spin=child_spin)
        p = _start(ctx, _empty_board, spec, 1 if pin else None)
        ch.watch(p)
        ends.append(ch)
        procs.append(p)
    for ch in ends:
        ch.wait_attached()
    fmu, io = ends
    pack = _ADVANCE.pack
    quantum_ns = 1_000_000
    t_virtual = [0]

    def run(k: int) -> float:
        t = t_virtual[0]
        fsend, frecv, isend, irecv = fmu.send, fmu.recv, io.send, io.recv
        t0 = time.perf_counter()
        for _ in range(k):
            t += quantum_ns
            msg = pack(t)
            fsend(msg)
            isend(msg)
            _busy(parent_work_us)
            frecv()
            irecv()
        dt = time.perf_counter() - t0
        t_virtual[0] = t
        return dt

    try:
        return _median_us(run, n, runs)
    finally:
        for ch in ends:
            ch.close()
        for p in procs:
            p.join(5)
        os.sched_setaffinity(0, saved_affinity)


# ------------------------------------------------------------------------------ script
def _policies() -> dict[str, tuple[SpinPolicy, SpinPolicy]]:
    """(parent, child) receive policies compared by the script."""
    def fixed(us: float, y: bool) -> SpinPolicy:
        return SpinPolicy(max_us=us, adaptive=False, yield_cpu=y)

    return {
        "block (no spin)": (fixed(0, False), fixed(0, False)),
        "spin 50us, no yield": (fixed(50, False), fixed(50, False)),
        "spin 50us + yield": (fixed(50, True), fixed(50, True)),
        "spin 200us + yield": (fixed(200, True), fixed(200, True)),
        "spin 1ms + yield": (fixed(1000, True), fixed(1000, True)),
        "adaptive (default)": (SpinPolicy(), SpinPolicy()),
    }


def main(argv: list[str] | None = None) -> None:
    args = sys.argv[1:] if argv is None else argv
    quick = "--quick" in args
    n = 5000 if quick else N
    print(f"# {os.cpu_count()} cpus, n={n}, median of {RUNS} runs")
    print(f"pipe round trip             : {bench_pipe_roundtrip_us(n):7.2f} us")
    print(f"channel round trip          : {bench_channel_roundtrip_us(n):7.2f} us")
    lo = bench_lockstep_overhead_us_per_quantum(n)
    print(f"lockstep, 2 empty boards    : {lo:7.2f} us/quantum")
    lw = bench_lockstep_overhead_us_per_quantum(n, parent_work_us=15.0)
    print(f"  same, +15 us parent work  : {lw:7.2f} us/quantum (transport {lw - 15:.2f})")
    if "--all" not in args:
        return
    print(f"eventfd wake round trip     : {bench_eventfd_roundtrip_us(n):7.2f} us")
    for name, (ps, cs) in _policies().items():
        rt = bench_channel_roundtrip_us(n, spin=ps, child_spin=cs)
        l0 = bench_lockstep_overhead_us_per_quantum(n, spin=ps, child_spin=cs)
        l15 = bench_lockstep_overhead_us_per_quantum(n, parent_work_us=15, spin=ps, child_spin=cs)
        print(f"{name:20s}: rt {rt:6.2f} us | lockstep {l0:6.2f} us/q | "
              f"+15us work {l15:6.2f} us/q (transport {l15 - 15:6.2f})")


if __name__ == "__main__":
    main()
