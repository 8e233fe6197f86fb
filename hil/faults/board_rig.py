"""Faults on boards built in-process: the catalogue's rig for a plain pytest test.

A driver test builds an :class:`fmu.board.FmuV2Board` (or the IO board, or a variant from a
spec) and runs its kernel; :class:`BoardRig` applies catalogue faults to it through the same
control hooks the orchestrated system uses (``board.call("fault", ...)``, ``ctl_i2c_fault``,
``ctl_spi_miso_stuck``, ...), so a kind means the same thing on both rigs and acts on the
board's own registers, buses and wires. Targets come from each board's ``spec``: a variant
with a second compass has that compass among the sensor faults' targets.

Timed steps (a fault's duration) are kernel events on the board the time is read from, so
they happen in virtual time while the test runs the kernel, between the same events as on a
real rig. Kinds that need the orchestrator (a killed process, a wire between two board
processes) or devices the rig was not given (``dev``: world, rc, gcs) raise
:class:`FaultError` saying so.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from hil.faults import FaultError, FaultRunner

__all__ = ["BoardRig"]


class BoardRig(FaultRunner):
    """A fault rig over in-process boards: ``BoardRig(fmu)``, ``BoardRig(fmu, io)``.

    Boards are known by their ``name`` (``fmu``, ``io``), as in the orchestrated system; the
    first board's kernel is the clock (in-process boards in one test share one time base or run
    alone). ``dev`` optionally adds outside devices for the kinds that act on them.
    """

    def __init__(self, *boards: Any, dev: dict[str, Any] | None = None) -> None:
        super().__init__()
        if not boards:
            raise FaultError("BoardRig needs at least one board")
        self._boards: dict[str, Any] = {}
        for b in boards:
            if b.name in self._boards:
                raise FaultError(f"BoardRig: two boards named {b.name!r}")
            self._boards[b.name] = b
        self._clock = boards[0].kernel
        self.orch = None
        self.dev = dict(dev or {})

    def board(self, name: str) -> Any:
        try:
            return self._boards[name]
        except KeyError:
            raise FaultError(f"no board {name!r} (boards: {', '.join(self._boards)})") \
                from None

    @property
    def t_ns(self) -> int:
        now: int = self._clock.now_ns
        return now

    def boards(self) -> tuple[str, ...]:
        return tuple(self._boards)

    def call(self, board: str, method: str, *args: Any) -> Any:
        b = self.board(board)
        try:
            return b.call(method, *args)
        except (ValueError, KeyError, AttributeError) as exc:
            # the hook's refusal (no such bus, chip or hook on this board), as the
            # orchestrated rig reports it
            raise FaultError(str(exc).strip("'\"")) from None

    def spec(self, board: str) -> Any:
        b = self._boards.get(board)
        return None if b is None else getattr(b, "spec", None)

    def later(self, t_ns: int, fn: Callable[[int], None]) -> Any:
        k = self._clock
        return k.call_at(max(int(t_ns), k.now_ns), lambda: fn(k.now_ns))

    def cancel_later(self, handle: Any) -> None:
        self._clock.cancel(handle)
