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

from dataclasses import dataclass, field
from typing import Any, Callable, Protocol

__all__ = ["CATALOGUE", "Fault", "FaultError", "FaultKind", "Rig", "fault_kind", "get_kind"]

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
