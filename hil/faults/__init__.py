"""The fault catalogue: every fault fmu-hil can inject, as data.

A :class:`FaultKind` names a fault, the level it acts at (``sensor``, ``bus``, ``rc``, ``gps``,
``board``, ``vehicle``, ``link``), the targets it accepts, its parameters with defaults, and two
functions: ``start`` applies it to a running rig at a virtual time, ``stop`` undoes it (``None``
for faults that cannot be undone, such as a lost propeller). Most kinds set one hook and clear
it again: :func:`switch_kind` writes such a kind as one ``apply(rig, target, params, on)``.

A rig is what the kinds act on (:class:`Rig`): the orchestrated system
(:class:`Injector`) or boards built in-process in a test (:class:`hil.faults.board_rig.BoardRig`).
Both reach a board only through its control hooks (``board.call("fault", ...)``, ``ctl_*``:
registers, buses and wires of the board's own objects); a kind whose targets depend on the
board (the sensor chips) takes them from the board's spec (:mod:`board.specs`), so a board
variant with another chip can have that chip faulted. Each kind acts where the fault
happens on real hardware: on a chip's registers or pins, on a bus or a wire, on the RC
receiver's output, in the world's physics, or on the ground link; never on the flight stack's
own state.

Kinds register themselves with :func:`fault_kind` from the modules of this package, grouped by
level; :data:`CATALOGUE` maps each name to its kind. A scenario's timeline holds
:class:`Fault` instances (a kind plus target, parameters, start time and a duration or an end
condition).
"""

from __future__ import annotations

import heapq
import importlib
import pkgutil
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

__all__ = ["CATALOGUE", "LOAD_ERRORS", "ActiveFault", "Fault", "FaultError", "FaultKind",
           "FaultRunner", "Injector", "Rig", "fault_kind", "get_kind", "load_kinds", "orch_call",
           "switch_kind"]

LEVELS = ("sensor", "bus", "rc", "gps", "board", "vehicle", "link")


class FaultError(ValueError):
    """A fault was named or parameterised wrongly (unknown kind, target or parameter)."""


class Rig(Protocol):
    """What a fault acts on: the orchestrated system or in-process boards.

    ``call`` reaches a board's control hook (``ctl_<method>``), the one way kinds change a
    board; ``spec`` is the board's :class:`board.specs.BoardSpecData` (targets come from it);
    ``later`` runs a step at a later virtual time. ``orch`` is the orchestrator, ``None`` on
    in-process boards (kinds that need it, a killed process or a cut inter-board wire, say so
    with a :class:`FaultError`); ``dev`` holds the devices outside the boards (world, rc, gcs).
    """

    orch: Any
    dev: dict[str, Any]

    @property
    def t_ns(self) -> int: ...

    def boards(self) -> tuple[str, ...]: ...

    def call(self, board: str, method: str, *args: Any) -> Any: ...

    def spec(self, board: str) -> Any: ...

    def later(self, t_ns: int, fn: Callable[[int], None]) -> Any: ...


StartFn = Callable[[Rig, str, dict[str, Any], int], Any]
StopFn = Callable[[Rig, str, dict[str, Any], int, Any], None]
#: ``apply(rig, target, params, on)``: set the fault (on) or clear it (off)
ApplyFn = Callable[[Rig, str, dict[str, Any], bool], Any]
#: a board spec -> the targets a kind has on that board
SpecTargetsFn = Callable[[Any], tuple[str, ...]]


@dataclass(frozen=True)
class FaultKind:
    name: str
    level: str
    doc: str
    start: StartFn
    targets: tuple[str, ...] = ()
    params: dict[str, Any] = field(default_factory=dict)
    stop: StopFn | None = None
    #: the board whose spec gives the targets, and how (``None``: the fixed ``targets``)
    spec_board: str = ""
    spec_targets: SpecTargetsFn | None = None

    def targets_on(self, rig: Rig | None) -> tuple[str, ...]:
        """The targets this kind has on ``rig``: from its board's spec when the kind says how
        and the rig knows the spec, else :attr:`targets` (the standard FMUv2/IOv2 ones)."""
        if self.spec_targets is None or not hasattr(rig, "spec"):
            return self.targets
        spec = rig.spec(self.spec_board)  # type: ignore[union-attr]
        return self.targets if spec is None else self.spec_targets(spec)

    def check(self, target: str, params: dict[str, Any],
              targets: tuple[str, ...] | None = None) -> dict[str, Any]:
        """The parameters with defaults filled in; raises :class:`FaultError` on a bad target
        (one of ``targets``, default :attr:`targets`) or an unknown parameter."""
        targets = self.targets if targets is None else targets
        if targets and target not in targets:
            raise FaultError(f"fault {self.name}: target {target!r} is not one of "
                             f"{', '.join(targets)}")
        unknown = set(params) - set(self.params)
        if unknown:
            raise FaultError(f"fault {self.name}: unknown parameter(s) {', '.join(sorted(unknown))}"
                             f" (known: {', '.join(self.params) or 'none'})")
        return {**self.params, **params}


CATALOGUE: dict[str, FaultKind] = {}


def fault_kind(name: str, *, level: str, doc: str, targets: tuple[str, ...] = (),
               spec_board: str = "", spec_targets: SpecTargetsFn | None = None,
               **params: Any) -> Callable[[StartFn], StartFn]:
    """Register the decorated ``start(rig, target, params, t_ns) -> token`` as fault ``name``.

    The decorated function gains a ``.stopper`` decorator for its
    ``stop(rig, target, params, t_ns, token)``: for kinds whose undoing is not the same hook
    cleared (a token to give back, steps in time); the others are :func:`switch_kind`.
    ``spec_targets(spec)`` derives the targets from the spec of board ``spec_board``
    (``targets`` then lists the standard board's, for the catalogue listing).
    """
    if level not in LEVELS:
        raise FaultError(f"fault {name}: level {level!r} is not one of {', '.join(LEVELS)}")
    if name in CATALOGUE:
        raise FaultError(f"fault {name} registered twice")

    def deco(start: StartFn) -> StartFn:
        CATALOGUE[name] = FaultKind(name, level, doc, start, targets, dict(params),
                                    spec_board=spec_board, spec_targets=spec_targets)

        def stopper(stop: StopFn) -> StopFn:
            kind = CATALOGUE[name]
            CATALOGUE[name] = FaultKind(kind.name, kind.level, kind.doc, kind.start,
                                        kind.targets, kind.params, stop, kind.spec_board,
                                        kind.spec_targets)
            return stop

        start.stopper = stopper  # type: ignore[attr-defined]
        return start

    return deco


def switch_kind(name: str, apply: ApplyFn, *, level: str, doc: str,
                targets: tuple[str, ...] = (), spec_board: str = "",
                spec_targets: SpecTargetsFn | None = None, **params: Any) -> FaultKind:
    """Register fault ``name`` as one hook that is set on start and cleared on stop:
    ``apply(rig, target, params, True)`` starts it, ``apply(..., False)`` stops it (what
    ``apply`` returns on start is the token). The general form of the catalogue's start/stop
    pairs, which differed only in the value they gave the same hook."""

    def start(rig: Rig, target: str, params: dict[str, Any], t_ns: int) -> Any:
        return apply(rig, target, params, True)

    def stop(rig: Rig, target: str, params: dict[str, Any], t_ns: int, token: Any) -> None:
        apply(rig, target, params, False)

    registered: Any = fault_kind(name, level=level, doc=doc, targets=targets,
                                 spec_board=spec_board, spec_targets=spec_targets, **params)(start)
    registered.stopper(stop)
    return CATALOGUE[name]


def get_kind(name: str) -> FaultKind:
    try:
        return CATALOGUE[name]
    except KeyError:
        raise FaultError(f"unknown fault {name!r}; known: {', '.join(sorted(CATALOGUE))}") \
            from None


@dataclass
class Fault:
    """One fault on a scenario's timeline."""

    kind: str
    target: str = ""
    params: dict[str, Any] = field(default_factory=dict)
    at_s: float = 0.0                 # virtual time of the start, from the scenario's t=0
    duration_s: float | None = None   # None: until ``until`` holds, or for ever
    until: str | None = None          # an end condition (the scenario engine evaluates it)
    name: str | None = None           # the event it raises (default: the kind's name)

    @property
    def event(self) -> str:
        return self.name or self.kind


NS_PER_S = 1_000_000_000


@dataclass
class ActiveFault:
    """A fault applied to a rig: what :meth:`FaultRunner.stop` needs to undo it."""

    kind: FaultKind
    target: str
    params: dict[str, Any]
    t_start_ns: int
    token: Any = None
    t_stop_ns: int | None = None
    timer: Any = None                  # the scheduled stop (a handle of the rig's later)

    @property
    def active(self) -> bool:
        return self.t_stop_ns is None


class FaultRunner:
    """Applies catalogue faults to a rig, in virtual time: the part of a :class:`Rig` that
    does not depend on what the boards run in.

    Subclasses say how to reach a board (``call``), where the time and the specs come from and
    how to run a step later: :class:`Injector` for the orchestrated system,
    :class:`hil.faults.board_rig.BoardRig` for boards built in-process.
    """

    orch: Any = None
    dev: dict[str, Any]

    def __init__(self) -> None:
        self.history: list[ActiveFault] = []
        self.log: Callable[[str], None] = lambda msg: None

    # -- what a rig provides (see Rig) ---------------------------------------------------------

    @property
    def t_ns(self) -> int:
        raise NotImplementedError

    def boards(self) -> tuple[str, ...]:
        raise NotImplementedError

    def call(self, board: str, method: str, *args: Any) -> Any:
        """A board's control hook ``ctl_<method>(*args)``; an unknown board or a refusal (a bad
        bus name, a bad rate) raises :class:`FaultError`."""
        raise NotImplementedError

    def spec(self, board: str) -> Any:
        """The board's spec (None if this rig has no such board)."""
        raise NotImplementedError

    def later(self, t_ns: int, fn: Callable[[int], None]) -> Any:
        """Call ``fn(now)`` at virtual time ``t_ns`` (or the first moment the rig sees after
        it); returns a handle for :meth:`cancel_later`."""
        raise NotImplementedError

    def cancel_later(self, handle: Any) -> None:
        raise NotImplementedError

    # -- applying faults -----------------------------------------------------------------------

    def start(self, kind: str, target: str = "", params: dict[str, Any] | None = None, *,
              duration_s: float | None = None) -> ActiveFault:
        """Apply a fault now; with ``duration_s`` it stops by itself that much later."""
        k = get_kind(kind)
        targets = k.targets_on(self)
        if not target and targets:
            target = targets[0]
        full = k.check(target, dict(params or {}), targets)
        if duration_s is not None:
            if k.stop is None:
                raise FaultError(f"fault {kind} cannot be undone, so it takes no duration")
            if duration_s < 0:
                raise FaultError(f"fault {kind}: negative duration {duration_s}")
        now = self.t_ns
        token = k.start(self, target, full, now)
        af = ActiveFault(k, target, full, now, token)
        self.history.append(af)
        self.log(f"t={now / NS_PER_S:.3f} s: fault {kind} {target} {full or ''}".rstrip())
        if duration_s is not None:
            af.timer = self.later(now + round(duration_s * NS_PER_S), lambda t: self.stop(af))
        return af

    def stop(self, af: ActiveFault) -> None:
        """Undo a fault (no-op if it already stopped or cannot be undone)."""
        if not af.active:
            return
        if af.timer is not None:
            self.cancel_later(af.timer)
        af.t_stop_ns = self.t_ns
        if af.kind.stop is not None:
            af.kind.stop(self, af.target, af.params, af.t_stop_ns, af.token)
            self.log(f"t={af.t_stop_ns / NS_PER_S:.3f} s: fault {af.kind.name} {af.target} "
                     f"cleared")


def orch_call(orch: Any, board: str, method: str, *args: Any) -> Any:
    """A control hook of a board process through the orchestrator; its refusal (sent back as a
    RuntimeError naming the remote error) becomes a :class:`FaultError`."""
    boards = getattr(orch, "handles", ("fmu", "io"))
    if board not in boards:
        raise FaultError(f"no board {board!r} (boards: {', '.join(sorted(boards))})")
    try:
        return orch.call(board, method, *args)
    except RuntimeError as exc:
        raise FaultError(str(exc).strip().splitlines()[-1]) from None


class Injector(FaultRunner):
    """Applies catalogue faults to the orchestrated system (:func:`hil.system.build_system`).

    It is the :class:`Rig` the kinds act on (``orch``, ``dev``) and adds a timer list: faults
    with a duration stop at their virtual end, and kinds that act in steps (a crash now, a
    reboot later) call :meth:`later`. :meth:`install` hooks it into the orchestrator's
    ``on_quantum`` so timers fire on the quantum they are due, whoever advances the clock (a
    scenario, a GCS helper waiting for an acknowledgement, a test).
    """

    def __init__(self, orch: Any, dev: dict[str, Any]) -> None:
        super().__init__()
        self.orch = orch
        self.dev = dev
        self._timers: list[list] = []   # [t_ns, seq, fn] (fn None: cancelled)
        self._seq = 0
        self._installed = False

    def install(self) -> Injector:
        """Hook into the orchestrator: timers on every quantum, and the boards'
        MAV_CMD_INJECT_FAILURE requests (:mod:`hil.faults.inject_failure`)."""
        if not self._installed:
            self.orch.on_quantum.append(lambda orch: self.tick())
            hooks = getattr(self.orch, "request_hooks", None)
            if hooks is not None:
                from hil.faults.inject_failure import FailureInjection

                self.failure_injection = FailureInjection(self)
                hooks["failure_request"] = self.failure_injection.handle
            self._installed = True
        return self

    @property
    def t_ns(self) -> int:
        return int(self.orch.t_ns)

    def boards(self) -> tuple[str, ...]:
        return tuple(getattr(self.orch, "handles", ("fmu", "io")))

    def call(self, board: str, method: str, *args: Any) -> Any:
        return orch_call(self.orch, board, method, *args)

    def spec(self, board: str) -> Any:
        """The orchestrated system runs the standard boards: FMUv2 and IOv2."""
        from board.specs import FMU_V2, IO_V2

        return {"fmu": FMU_V2, "io": IO_V2}.get(board) if board in self.boards() else None

    def later(self, t_ns: int, fn: Callable[[int], None]) -> list:
        """Call ``fn(t_ns)`` on the first quantum boundary at or after ``t_ns``."""
        entry = [int(t_ns), self._seq, fn]
        self._seq += 1
        heapq.heappush(self._timers, entry)
        return entry

    def cancel_later(self, handle: list) -> None:
        handle[2] = None

    def tick(self) -> None:
        now = self.orch.t_ns
        timers = self._timers
        while timers and timers[0][0] <= now:
            t_ns, _, fn = heapq.heappop(timers)
            if fn is not None:
                fn(now)


#: modules of this package that failed to import: name -> error text
LOAD_ERRORS: dict[str, str] = {}


def load_kinds() -> dict[str, FaultKind]:
    """Import every module of this package, so each registers its kinds.

    Tolerant by design: the modules are found on disk (``pkgutil``), so a kind module added
    later joins the catalogue with no list to edit; a module that fails to import is recorded
    in :data:`LOAD_ERRORS` (``hil faults`` and the tests report it) instead of taking the whole
    catalogue down.
    """
    for info in pkgutil.iter_modules(__path__):
        name = f"{__name__}.{info.name}"
        if info.name.startswith("_"):
            continue
        try:
            importlib.import_module(name)
        except Exception as exc:  # noqa: BLE001 - reported, see LOAD_ERRORS
            LOAD_ERRORS[name] = f"{type(exc).__name__}: {exc}"
    return CATALOGUE


load_kinds()

from hil.faults.board_rig import BoardRig  # noqa: E402 - builds on FaultRunner above

__all__ += ["BoardRig"]
