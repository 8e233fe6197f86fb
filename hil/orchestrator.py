"""The orchestrator: one master clock for the boards and the world, quantum by quantum.

Each quantum ``(T, T + q]`` (an event at exactly T + q belongs to it):

1. every live board is told "advance to T + q" with the records addressed to it (posted to all
   boards first, so the board processes run in parallel);
2. meanwhile the world (JSBSim) steps to T + q in this process;
3. every board's outputs (stamped inside the quantum) are collected and routed along the wiring
   to the inputs of the next quantum.

So a record crosses a wire one quantum after the quantum it was produced in. Its stamp is kept:
a byte sent at t arrives at t plus its wire time if that is still ahead of the receiver, and at
the start of the next quantum otherwise. The added latency is therefore at most one quantum.

A board with no inputs and no event due inside a quantum is not asked to advance at all (an
exchange costs more than the quantum's work of an idle chip). When it is next asked, it first
catches up to the quantum's start, so skipping never changes results.

Results never depend on pacing: pacing only sleeps between quanta (wall clock, allowed in hil/).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable

from board.endpoint import BoardDied, LocalHandle
from board.protocols import BoardHandle
from board.wiring import WORLD, Wire
from hil.cpu_plan import CpuPlan
from hil.devices import HostDevice
from hil.wire_faults import WireFault, WireFaults
from hil.trace import TraceWriter

__all__ = ["BoardSpec", "Orchestrator", "BoardDied", "TraceWriter"]

NS_PER_S = 1_000_000_000
#: spin budget of every channel when the FMU has a CPU of its own (Orchestrator._spin_policy).
#: Still adaptive: a run whose waits average more than this blocks instead. Measured on the
#: default flight: 2 ms gave about half the gain of 20 ms, because the rare long waits (start-up,
#: a burst of shell or MAVLink work) lift the running average over a small budget.
PINNED_SPIN_US = 20000.0


@dataclass(frozen=True)
class BoardSpec:
    """How to build a board: a factory ``"module:callable"`` and plain-data keyword arguments."""

    factory: str
    kwargs: dict[str, Any] = field(default_factory=dict)


class Orchestrator(WireFaults):
    """Runs boards (as processes, or in this process) and an optional world in lockstep."""

    def __init__(self, boards: dict[str, BoardSpec], wiring: Iterable[Wire] = (),
                 world: HostDevice | None = None, quantum_ns: int = 1_000_000,
                 mode: str = "process",
                 speed: float | None = None, trace_path: str | None = None,
                 start_method: str = "spawn", keep_running_on_death: bool = True,
                 log: Callable[[str], None] | None = None, pipeline: bool = False,
                 isolate: str | None = None) -> None:
        if quantum_ns <= 0 or type(quantum_ns) is not int:
            raise ValueError(f"quantum must be a positive integer ns, got {quantum_ns!r}")
        if mode not in ("process", "local"):
            raise ValueError(f"mode must be 'process' or 'local', got {mode!r}")
        if speed is not None and speed <= 0:
            raise ValueError(f"speed factor must be positive, got {speed}")
        self.specs = dict(boards)
        self.wiring = list(wiring)
        self.world = world
        self.quantum_ns = quantum_ns
        self.mode = mode
        self.speed = speed
        self.start_method = start_method
        self.keep_running_on_death = keep_running_on_death
        self.log = log or (lambda msg: None)
        self.t_ns = 0
        self.quanta = 0
        self.handles: dict[str, BoardHandle] = {}
        self.dead: dict[str, str] = {}
        self._inbox: dict[str, list] = {name: [] for name in boards}
        #: boards that expose a "reboot" output, reboots requested this quantum, reboot counts
        self._reboot_boards: set[str] = set()
        self._reboot_pending: list[str] = []
        self.reboots: dict[str, int] = {}
        #: what boards ask of the host on an ``X_request`` output: ``hook(board, payload)``
        #: per port returns the payload answered on the board's ``X_reply`` input (None: no
        #: answer). The fault injector serves "failure_request" (hil.faults.Injector.install).
        self.request_hooks: dict[str, Callable[[str, Any], Any]] = {}
        self._request_boards: set[str] = set()
        self._requests: list[tuple[str, str, Any]] = []
        #: next event time each board reported (None: nothing scheduled); 0 forces an exchange
        self._next_ns: dict[str, int | None] = {name: 0 for name in boards}
        self.skip_idle = True
        self.exchanges = 0
        #: Lookahead: each board is handed the next quantum before the orchestrator waits for
        #: the present one, so boards never idle while the orchestrator routes and steps the
        #: world (see :meth:`_step_pipelined`).
        self.pipeline = pipeline
        #: pipelined mode: advances posted and not yet waited for, (until_ns, inputs), per board
        self._pending: dict[str, list[tuple[int, list]]] = {name: [] for name in boards}
        #: pipelined mode: the end of the last quantum handed to each board
        self._posted_to: dict[str, int] = {name: 0 for name in boards}
        self._routes: dict[tuple[str, str], list[tuple[str, str]]] = {}
        #: faults on wires: (board, output port) -> what the wire does to each record
        self._wire_faults: dict[tuple[str, str], WireFault] = {}
        #: how a quantum's records are routed: the plain :meth:`_route_all`, or while a wire has
        #: a fault :meth:`_route_all_faulty` (hil/wire_faults.py), so a healthy run pays nothing
        self._route_outputs: Callable[[str, list], None] = self._route_all
        self._trace = TraceWriter(trace_path, quantum_ns, self.specs) if trace_path else None
        self._wall_start: float | None = None
        self._wall_elapsed = 0.0
        self._t_at_wall_start = 0
        self.on_quantum: list[Callable[[Orchestrator], None]] = []
        #: process mode: the board given a CPU of its own (see :class:`CpuPlan`)
        if isolate is not None and isolate not in self.specs:
            raise ValueError(f"isolate: no board {isolate!r} (boards: {', '.join(self.specs)})")
        self.isolate = isolate
        self.cpu_plan: CpuPlan | None = None
        self._started = False
        self._check_wiring()

    # -- set-up ----------------------------------------------------------------------------

    def _check_wiring(self) -> None:
        for w in self.wiring:
            for end in (w.src, w.dst):
                if end[0] != WORLD and end[0] not in self.specs:
                    raise ValueError(f"wire {w}: no board named {end[0]!r}")
            if (w.src[0] == WORLD or w.dst[0] == WORLD) and self.world is None:
                raise ValueError(f"wire {w} needs a world, and none was given")
            self._routes.setdefault(w.src, []).append(w.dst)
        if self.world is not None:
            wired = {port for board, port in self._routes if board == WORLD}
            wired |= {dst[1] for dsts in self._routes.values() for dst in dsts
                      if dst[0] == WORLD}
            if hasattr(self.world, "lead_ns"):
                self.world.lead_ns = self.quantum_ns
            if hasattr(self.world, "set_wired"):
                self.world.set_wired(wired)
            elif hasattr(self.world, "wired"):
                self.world.wired = wired

    def start(self) -> Orchestrator:
        """Start every board (processes start in parallel) and check the wiring's port names."""
        if self._started:
            return self
        self._started = True
        try:
            if self.mode == "process":
                from hil.boardproc import ProcessHandle

                if self.isolate is not None:
                    self.cpu_plan = CpuPlan.make(self.isolate, log=self.log)
                spin = self._spin_policy()
                for name, spec in self.specs.items():
                    self.handles[name] = ProcessHandle(name, spec.factory, spec.kwargs,
                                                       self.start_method, spin=spin)
                if self.cpu_plan is not None:
                    self.cpu_plan.apply(self.handles)
            else:
                from hil.boardproc import resolve_kwargs

                for name, spec in self.specs.items():
                    self.handles[name] = LocalHandle(name, spec.factory,
                                                     resolve_kwargs(spec.kwargs))
            self._reboot_boards = {n for n, h in self.handles.items()
                                   if any(p[0] == "reboot" for p in h.ports)}
            self._request_boards = self._reboot_boards | {
                n for n, h in self.handles.items() if any(p[0].endswith("_request")
                                                          for p in h.ports)}
            for w in self.wiring:
                for (board, port), want in ((w.src, ("out", "inout")), (w.dst, ("in", "inout"))):
                    if board == WORLD:
                        continue
                    ports = {p[0]: p for p in self.handles[board].ports}
                    if port not in ports:
                        raise ValueError(f"wire {w}: board {board} has no port {port!r} "
                                         f"(ports: {', '.join(sorted(ports)) or 'none'})")
                    if ports[port][2] not in want:
                        raise ValueError(f"wire {w}: port {board}.{port} is an "
                                         f"{ports[port][2]!r} port")
        except BaseException:
            self.close()
            raise
        return self

    def _spin_policy(self) -> Any:
        """How the channels wait: :class:`hil.ipc.SpinPolicy`'s default, except that with the
        FMU pinned and no pacing, waiters spin up to :data:`PINNED_SPIN_US` before blocking.
        Then no waiter ever competes with the FMU for its core, and on the shared core a
        spinner's ``sched_yield`` hands the CPU to the process it waits for, so a message
        costs no semaphore wake-up (a futex system call, and waking the peer's virtual CPU:
        30-40 us here) on either side. Paced runs keep the default: their waits are long,
        and spinning through them would only burn CPU."""
        if self.cpu_plan is None or self.speed is not None:
            return None
        from hil.ipc import SpinPolicy

        return SpinPolicy(max_us=PINNED_SPIN_US)

    # -- running -------------------------------------------------------------------------------

    def step(self) -> None:
        """Advance everything by one quantum."""
        if not self._started:
            self.start()
        if self.pipeline:
            self._step_pipelined()
            return
        start = self.t_ns
        until = start + self.quantum_ns
        inbox = self._inbox
        next_ns = self._next_ns
        skip = self.skip_idle
        dead = self.dead
        check_alive = not self.quanta & 15  # a skipped board's process is checked every 16
        live = []
        trace = self._trace
        sent: dict[str, list] = {}
        for name, handle in self.handles.items():
            if dead and name in dead:
                continue
            inputs = inbox[name]
            if skip and not inputs:
                due = next_ns[name]
                if (due is None or due > until) and (not check_alive or handle.is_alive()):
                    continue  # idle
            inbox[name] = []  # a fresh list: this quantum's outputs are routed into it
            if trace is not None:
                sent[name] = inputs
            handle.post_advance(start, until, inputs)
            live.append((name, handle))
        self.exchanges += len(live)
        self._run_world(until)
        for name, handle in live:
            try:
                outputs, next_ns[name] = handle.wait_advance()
            except BoardDied as died:
                self._board_died(name, died.detail, until)
                continue
            self._received(name, until, sent.get(name), outputs)
        self._end_quantum(until)

    def _received(self, name: str, until: int, inputs: list | None, outputs: list) -> None:
        """A board's outputs of the quantum ending at ``until``: trace, route, note a reboot."""
        if self._trace is not None:
            self._trace.write(name, until, inputs, outputs)
        if outputs:
            self._route_outputs(name, outputs)
            if name in self._request_boards:
                for rec in outputs:
                    if rec[0] == "reboot" and name in self._reboot_boards:
                        if name not in self._reboot_pending:
                            self._reboot_pending.append(name)
                    elif rec[0] in self.request_hooks:
                        self._requests.append((name, rec[0], rec[2]))

    def _end_quantum(self, until: int) -> None:
        self.t_ns = until
        while self._requests:  # before a reboot, so the answer reaches the board that asked
            name, port, payload = self._requests.pop(0)
            reply = self.request_hooks[port](name, payload)
            if reply is not None and name not in self.dead:
                self._inbox[name].append((port[:-len("request")] + "reply", self.t_ns, reply))
        while self._reboot_pending:
            self._restart(self._reboot_pending.pop(0))
        self.quanta += 1
        for hook in self.on_quantum:
            hook(self)
        if self.speed is not None:
            self._pace()

    def _step_pipelined(self) -> None:
        """One quantum with lookahead.

        Each board already holds the quantum ``[t, t+q)`` (posted one step earlier). The world
        steps to ``t+q``; then every board is handed ``[t+q, t+2q)`` with what has been routed
        to it so far, and only then does the orchestrator wait for ``[t, t+q)``. A board thus
        goes from one quantum to the next without waiting for the orchestrator's turn, and on
        two cores the FMU, the IO and the world run side by side. The price is latency between
        boards: a record a board sends in quantum k reaches another board in quantum k+2 (at
        most two quanta late, stamps kept). The world's records still reach the boards, and
        theirs the world, at most one quantum late. Deterministic like the plain step: what
        each quantum receives depends only on quantum indices. Idle boards are not skipped.
        """
        start = self.t_ns
        q = self.quantum_ns
        until = start + q
        dead = self.dead
        posted = self._posted_to
        live = [(n, h) for n, h in self.handles.items() if not (dead and n in dead)]
        for name, handle in live:  # a board not yet ahead (first quantum, reboot, drained)
            if posted[name] < until:
                self._post(name, handle, posted[name] if posted[name] > start else start, until)
        self._run_world(until)
        for name, handle in live:
            if name not in dead and posted[name] < until + q:
                self._post(name, handle, posted[name], until + q)
        for name, handle in live:
            self._collect(name, handle, until)
        self._end_quantum(until)

    def _post(self, name: str, handle: BoardHandle, start: int, until: int) -> None:
        inputs = self._inbox[name]
        self._inbox[name] = []
        handle.post_advance(start, until, inputs)
        self._pending[name].append((until, inputs))
        self._posted_to[name] = until
        self.exchanges += 1

    def _collect(self, name: str, handle: BoardHandle, upto: int) -> None:
        """Wait for a board's posted quanta ending at or before ``upto`` and route what they
        sent (pipelined mode)."""
        pending = self._pending[name]
        while pending and pending[0][0] <= upto and name not in self.dead:
            until, inputs = pending.pop(0)
            try:
                outputs, self._next_ns[name] = handle.wait_advance()
            except BoardDied as died:
                pending.clear()
                self._board_died(name, died.detail, until)
                return
            self._received(name, until, inputs, outputs)

    def _drain(self, name: str) -> None:
        """Pipelined mode: finish every quantum already handed to this board (before a
        control call, so that the board is not running while it is asked something)."""
        if self._pending[name]:
            self._collect(name, self.handles[name], self._pending[name][-1][0])

    def _run_world(self, until: int) -> None:
        """The world to ``until`` (it runs in this process, beside the boards' quanta), and its
        outputs routed to the boards' inboxes."""
        world = self.world
        if world is not None:
            world.run_until(until)
            out = world.outputs(until)
            if out:
                self._route_outputs(WORLD, out)

    def _route_all(self, board: str, records: list) -> None:
        """:meth:`_route` for a list of records (the per-quantum path, inlined)."""
        routes = self._routes
        inbox = self._inbox
        dead = self.dead
        world = self.world
        for rec in records:
            dsts = routes.get((board, rec[0]))
            if not dsts:
                continue  # an output nothing is wired to (an unconnected pin) goes nowhere
            for dst_board, dst_port in dsts:
                if dst_board == WORLD:
                    assert world is not None  # a wire to the world needs one (_check_wiring)
                    world.input(dst_port, rec[1], rec[2])
                elif dst_board not in dead:
                    inbox[dst_board].append(rec if dst_port == rec[0]
                                            else (dst_port, rec[1], rec[2]))

    def _route(self, board: str, port: str, t_ns: int, payload: Any) -> None:
        fault = self._wire_faults.get((board, port))
        if fault is not None:
            recs = fault.carry((port, t_ns, payload))
            if not recs:
                return
            port, t_ns, payload = recs[0]
        dsts = self._routes.get((board, port))
        if not dsts:
            return  # an output nothing is wired to (an unconnected pin) goes nowhere
        for dst_board, dst_port in dsts:
            if dst_board == WORLD:
                assert self.world is not None  # a wire to the world needs one (_check_wiring)
                self.world.input(dst_port, t_ns, payload)
            elif dst_board not in self.dead:
                self._inbox[dst_board].append((dst_port, t_ns, payload))

    def _restart(self, name: str) -> None:
        """Reboot a board that asked for it (``reboot`` on its console, MAVLink's
        PREFLIGHT_REBOOT): its process is replaced by a new one built from the same spec, which
        boots from its own time zero, as the real FMU's clock restarts; what it kept in FRAM
        (a host file) survives. The new board's times are offset by the reboot time."""
        old = self.handles[name]
        try:
            old.close(timeout_s=1.0)
        except Exception:
            pass
        spec = self.specs[name]
        if self.mode == "process":
            from hil.boardproc import ProcessHandle

            inner: Any = ProcessHandle(name, spec.factory, spec.kwargs, self.start_method,
                                       spin=self._spin_policy())
            if self.cpu_plan is not None:
                self.cpu_plan.apply({name: inner})
        else:
            from hil.boardproc import resolve_kwargs

            inner = LocalHandle(name, spec.factory, resolve_kwargs(spec.kwargs))
        from hil.boardproc import OffsetHandle

        self.handles[name] = OffsetHandle(inner, self.t_ns)
        self._inbox[name] = []
        self._next_ns[name] = 0
        self._pending[name] = []
        self._posted_to[name] = self.t_ns
        self.reboots[name] = self.reboots.get(name, 0) + 1
        self.log(f"hil: board {name} rebooted at t={self.t_ns / 1e9:.6f} s")

    def _board_died(self, name: str, detail: str, t_ns: int) -> None:
        self.dead[name] = detail
        self._pending[name] = []
        self.log(f"hil: board {name} died at t={t_ns / 1e9:.6f} s: {detail}")
        handle = self.handles[name]
        # A dead chip's outputs: UARTs fall silent (nothing more is sent), PWM pins stop
        # pulsing, driven pins are released.
        for port, kind, direction in handle.ports:
            if direction == "in":
                continue
            if kind == "pwm":
                self._route(name, port, t_ns, (0, 0))
            elif kind == "pin":
                self._route(name, port, t_ns, -1)
        try:
            handle.close(timeout_s=0.5)
        except Exception:
            pass
        if not self.keep_running_on_death:
            raise BoardDied(name, detail)

    def run(self, duration_ns: int | None = None, until_ns: int | None = None) -> None:
        """Run for ``duration_ns``, or until ``until_ns`` (rounded up to whole quanta)."""
        if (duration_ns is None) == (until_ns is None):
            raise ValueError("give exactly one of duration_ns and until_ns")
        end = self.t_ns + duration_ns if duration_ns is not None else until_ns
        assert end is not None
        if not self._started:
            self.start()
        t0 = time.perf_counter()
        if self._wall_start is None:
            self._wall_start = t0
            self._t_at_wall_start = self.t_ns
        try:
            while self.t_ns < end:
                self.step()
        finally:
            self._wall_elapsed += time.perf_counter() - t0

    def _pace(self) -> None:
        assert self.speed is not None and self._wall_start is not None
        target = self._wall_start + (self.t_ns - self._t_at_wall_start) / NS_PER_S / self.speed
        delay = target - time.perf_counter()
        if delay > 0.0005:
            time.sleep(delay)

    @property
    def rtf(self) -> float:
        """Virtual seconds per wall second spent in :meth:`run` so far."""
        if self._wall_elapsed <= 0:
            return 0.0
        return (self.t_ns - self._t_at_wall_start) / NS_PER_S / self._wall_elapsed

    def call(self, board: str, method: str, *args: Any) -> Any:
        """A control call on a board (shell command, fault injection, state query), made at the
        orchestrator's current time (a board skipped while idle catches up first)."""
        if board in self.dead:
            raise BoardDied(board, self.dead[board])
        handle = self.handles[board]
        if self.pipeline:
            self._drain(board)  # the board may be a quantum ahead of t_ns: it answers from there
            if board in self.dead:
                raise BoardDied(board, self.dead[board])
        elif self._started and self.t_ns > 0:
            handle.post_advance(self.t_ns, self.t_ns, [])
            outputs, self._next_ns[board] = handle.wait_advance()
            if self._trace is not None:
                self._trace.write(board, self.t_ns, [], outputs)
        if self._trace is not None:
            self._trace.call(board, method, args)
        result = handle.call(method, *args)
        self._next_ns[board] = 0  # a control call may have scheduled something
        return result

    def kill(self, board: str) -> None:
        """Kill a board's process abruptly (the 'FMU dead' fault); the next quantum notices."""
        handle = self.handles[board]
        self._next_ns[board] = 0  # exchange next quantum, so the death is seen at once
        if hasattr(handle, "kill"):
            handle.kill()
        else:
            handle.alive = False
            self._board_died(board, "killed", self.t_ns)

    def close(self) -> None:
        """Stop every board process and close the trace. Idempotent, safe after errors."""
        for handle in self.handles.values():
            try:
                handle.close()
            except Exception:
                pass
        if self._trace is not None:
            self._trace.close()
            self._trace = None
        if self.cpu_plan is not None:
            self.cpu_plan.restore()
            self.cpu_plan = None

    def __enter__(self) -> Orchestrator:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()
