"""The fault catalogue: every fault fmu-hil can inject, as data.

A :class:`FaultKind` names a fault, the level it acts at (``sensor``, ``bus``, ``rc``, ``gps``,
``board``, ``vehicle``, ``link``), the targets it accepts, its parameters with defaults, and two
functions: ``start`` applies it to a running rig at a virtual time, ``stop`` undoes it (``None``
for faults that cannot be undone, such as a lost propeller). Each kind acts where the fault
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
           "Injector", "Rig", "fault_kind", "get_kind", "load_kinds"]

LEVELS = ("sensor", "bus", "rc", "gps", "board", "vehicle", "link")


class FaultError(ValueError):
    """A fault was named or parameterised wrongly (unknown kind, target or parameter)."""


class Rig(Protocol):
    """What a fault acts on: a booted system (see :func:`hil.system.build_system`)."""

    orch: Any                   # hil.orchestrator.Orchestrator: t_ns, call(board, ...), kill()
    dev: dict[str, Any]         # the orchestrator-side devices: world, rc, gcs, safety, ...


StartFn = Callable[[Rig, str, dict[str, Any], int], Any]
StopFn = Callable[[Rig, str, dict[str, Any], int, Any], None]


@dataclass(frozen=True)
class FaultKind:
    name: str
    level: str
    doc: str
    start: StartFn
    targets: tuple[str, ...] = ()
    params: dict[str, Any] = field(default_factory=dict)
    stop: StopFn | None = None

    def check(self, target: str, params: dict[str, Any]) -> dict[str, Any]:
        """The parameters with defaults filled in; raises :class:`FaultError` on a bad target or
        an unknown parameter."""
        if self.targets and target not in self.targets:
            raise FaultError(f"fault {self.name}: target {target!r} is not one of "
                             f"{', '.join(self.targets)}")
        unknown = set(params) - set(self.params)
        if unknown:
            raise FaultError(f"fault {self.name}: unknown parameter(s) {', '.join(sorted(unknown))}"
                             f" (known: {', '.join(self.params) or 'none'})")
        return {**self.params, **params}


CATALOGUE: dict[str, FaultKind] = {}


def fault_kind(name: str, *, level: str, doc: str, targets: tuple[str, ...] = (),
               **params: Any) -> Callable[[StartFn], StartFn]:
    """Register the decorated ``start(rig, target, params, t_ns) -> token`` as fault ``name``.

    The decorated function gains a ``.stopper`` decorator for its
    ``stop(rig, target, params, t_ns, token)``.
    """
    if level not in LEVELS:
        raise FaultError(f"fault {name}: level {level!r} is not one of {', '.join(LEVELS)}")
    if name in CATALOGUE:
        raise FaultError(f"fault {name} registered twice")

    def deco(start: StartFn) -> StartFn:
        CATALOGUE[name] = FaultKind(name, level, doc, start, targets, dict(params))

        def stopper(stop: StopFn) -> StopFn:
            kind = CATALOGUE[name]
            CATALOGUE[name] = FaultKind(kind.name, kind.level, kind.doc, kind.start,
                                        kind.targets, kind.params, stop)
            return stop

        start.stopper = stopper  # type: ignore[attr-defined]
        return start

    return deco


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
    """A fault applied to a rig: what :meth:`Injector.stop` needs to undo it."""

    kind: FaultKind
    target: str
    params: dict[str, Any]
    t_start_ns: int
    token: Any = None
    t_stop_ns: int | None = None
    timer: list | None = None          # the scheduled stop, if any

    @property
    def active(self) -> bool:
        return self.t_stop_ns is None


class Injector:
    """Applies catalogue faults to a running rig, in virtual time.

    It is the :class:`Rig` the kinds act on (``orch``, ``dev``) and adds a timer list: faults
    with a duration stop at their virtual end, and kinds that act in steps (a crash now, a
    reboot later) call :meth:`later`. :meth:`install` hooks it into the orchestrator's
    ``on_quantum`` so timers fire on the quantum they are due, whoever advances the clock (a
    scenario, a GCS helper waiting for an acknowledgement, a test).
    """

    def __init__(self, orch: Any, dev: dict[str, Any]) -> None:
        self.orch = orch
        self.dev = dev
        self._timers: list[list] = []   # [t_ns, seq, fn] (fn None: cancelled)
        self._seq = 0
        self.history: list[ActiveFault] = []
        self.log: Callable[[str], None] = lambda msg: None
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

    def later(self, t_ns: int, fn: Callable[[int], None]) -> list:
        """Call ``fn(t_ns)`` on the first quantum boundary at or after ``t_ns``."""
        entry = [int(t_ns), self._seq, fn]
        self._seq += 1
        heapq.heappush(self._timers, entry)
        return entry

    def tick(self) -> None:
        now = self.orch.t_ns
        timers = self._timers
        while timers and timers[0][0] <= now:
            t_ns, _, fn = heapq.heappop(timers)
            if fn is not None:
                fn(now)

    def start(self, kind: str, target: str = "", params: dict[str, Any] | None = None, *,
              duration_s: float | None = None) -> ActiveFault:
        """Apply a fault now; with ``duration_s`` it stops by itself that much later."""
        k = get_kind(kind)
        if not target and k.targets:
            target = k.targets[0]
        full = k.check(target, dict(params or {}))
        if duration_s is not None:
            if k.stop is None:
                raise FaultError(f"fault {kind} cannot be undone, so it takes no duration")
            if duration_s < 0:
                raise FaultError(f"fault {kind}: negative duration {duration_s}")
        now = self.orch.t_ns
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
            af.timer[2] = None
        af.t_stop_ns = self.orch.t_ns
        if af.kind.stop is not None:
            af.kind.stop(self, af.target, af.params, af.t_stop_ns, af.token)
            self.log(f"t={af.t_stop_ns / NS_PER_S:.3f} s: fault {af.kind.name} {af.target} "
                     f"cleared")


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
