"""Helpers the hook modules share to reach a rig's parts with clear errors."""

from __future__ import annotations

from typing import Any

from hil.faults import FaultError, Rig, orch_call

__all__ = ["board_call", "device", "orchestrator", "world", "number", "vector"]


def board_call(rig: Rig, fault: str, board: str, method: str, *args: Any) -> Any:
    """A control hook of a board (``ctl_<method>``), on whatever rig: the one way a kind
    changes a board. A refusal (no such board, bus, UART or chip) becomes a FaultError naming
    the fault. A bare ``(orch, dev)`` rig without ``call`` (as some tests build around one
    board) is served through its ``orch.call``."""
    call = getattr(rig, "call", None)
    try:
        if call is None:
            return orch_call(rig.orch, board, method, *args)
        return call(board, method, *args)
    except FaultError as exc:
        raise FaultError(f"fault {fault}: {exc}") from None


def orchestrator(rig: Rig, fault: str) -> Any:
    """The orchestrator, for kinds that act between board processes (a killed or restarted
    process, a wire between two boards); in-process boards have none."""
    if rig.orch is None:
        raise FaultError(f"fault {fault} acts on the orchestrated system (a board process or a "
                         f"wire between boards); this rig has in-process boards "
                         f"({', '.join(rig.boards())})")
    return rig.orch


def device(rig: Rig, name: str, fault: str) -> Any:
    dev = rig.dev.get(name)
    if dev is None:
        raise FaultError(f"fault {fault}: this rig has no {name!r} device (devices: "
                         f"{', '.join(sorted(rig.dev)) or 'none'})")
    return dev


def world(rig: Rig, fault: str) -> Any:
    """The JSBSim :class:`hil.world.World` behind ``rig.dev["world"]``."""
    w = device(rig, "world", fault)
    return getattr(w, "world", w)


def number(params: dict[str, Any], key: str, fault: str, lo: float | None = None,
           hi: float | None = None) -> float:
    v = params[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or v != v:
        raise FaultError(f"fault {fault}: parameter {key} must be a number, got {v!r}")
    if (lo is not None and v < lo) or (hi is not None and v > hi):
        raise FaultError(f"fault {fault}: parameter {key}={v!r} is outside "
                         f"[{lo if lo is not None else '-inf'}, {hi if hi is not None else 'inf'}]")
    return float(v)


def vector(params: dict[str, Any], key: str, fault: str) -> tuple[float, float, float]:
    v = params[key]
    try:
        x, y, z = (float(c) for c in v)
    except (TypeError, ValueError):
        raise FaultError(f"fault {fault}: parameter {key} must be three numbers, got {v!r}") \
            from None
    return (x, y, z)
