"""The lockstep endpoint of a board: "advance to T with these stamped inputs" as plain messages.

The endpoint is the only door into a board from outside its process. Requests and replies are
``marshal``-encoded tuples of plain data, whichever way they travel:

* in another process (the default for ``hil``), through the shared-memory channel of
  :mod:`hil.ipc`, driven by :mod:`hil.boardproc`;
* in this process (unit tests, debugging), through :class:`LocalHandle`, which still encodes
  and decodes every message so that nothing but plain data ever crosses the boundary.

Requests: ``(OP_ADVANCE, start_ns, until_ns, inputs)``, ``(OP_CALL, method, args)``, ``(OP_STOP,)``.
Replies: ``(R_OK, outputs, next_event_ns)``, ``(R_RESULT, value)``, ``(R_ERROR, text)``.
A board whose firmware raised is dead, like a chip in a hard fault: its endpoint answers
``R_ERROR`` with the traceback, and the orchestrator stops advancing it.
"""

from __future__ import annotations

import importlib
import marshal
import traceback
from typing import Any, Final

from mypy_extensions import mypyc_attr

from board.board import Board, Record

__all__ = ["Endpoint", "LocalHandle", "BoardDied", "build_board", "OP_ADVANCE", "OP_CALL",
           "OP_STOP", "R_OK", "R_RESULT", "R_ERROR"]

OP_ADVANCE: Final = 0
OP_CALL: Final = 1
OP_STOP: Final = 2
R_OK: Final = 0
R_RESULT: Final = 1
R_ERROR: Final = 2

_dumps: Final = marshal.dumps
_loads: Final = marshal.loads


@mypyc_attr(native_class=False)
class BoardDied(RuntimeError):
    """A board stopped answering: its firmware raised, or its process died."""

    def __init__(self, board: str, detail: str) -> None:
        super().__init__(f"board {board} died: {detail}")
        self.board = board
        self.detail = detail


def build_board(factory: str, kwargs: dict[str, Any] | None = None) -> Board:
    """Build a board from ``"module:callable"`` and keyword arguments (plain data)."""
    module_name, _, attr = factory.partition(":")
    if not attr:
        raise ValueError(f"board factory {factory!r} must look like 'package.module:callable'")
    module = importlib.import_module(module_name)
    try:
        fn = getattr(module, attr)
    except AttributeError:
        raise ValueError(f"board factory {factory!r}: {module_name} has no {attr!r}") from None
    board = fn(**(kwargs or {}))
    if not isinstance(board, Board):
        raise TypeError(f"board factory {factory!r} returned {type(board).__name__}, not a Board")
    return board


class Endpoint:
    """Decodes requests, runs the board, encodes replies."""

    def __init__(self, board: Board) -> None:
        self.board = board
        self.alive = True

    def hello(self) -> bytes:
        """The first message a board sends: its name and ports."""
        return _dumps((R_RESULT, (self.board.name, self.board.ctl_ports())))

    def handle(self, request: bytes) -> bytes | None:
        """Handle one request; returns the reply, or None after OP_STOP."""
        msg = _loads(request)
        op = msg[0]
        if not self.alive:
            return _dumps((R_ERROR, f"board {self.board.name} is dead"))
        try:
            if op == OP_ADVANCE:
                out = self.board.advance(msg[2], msg[3], msg[1])
                return _dumps((R_OK, out, self.board.next_event_ns()))
            if op == OP_CALL:
                return _dumps((R_RESULT, self.board.call(msg[1], *msg[2])))
            if op == OP_STOP:
                return None
            return _dumps((R_ERROR, f"board {self.board.name}: unknown request op {op!r}"))
        except Exception:
            if op == OP_CALL:
                # A bad control call (unknown method, bad argument) is the caller's error; the
                # board itself keeps running.
                return _dumps((R_ERROR, traceback.format_exc()))
            self.alive = False
            return _dumps((R_ERROR, traceback.format_exc()))


class LocalHandle:
    """A board in this process, driven exactly like a board process (same messages)."""

    def __init__(self, name: str, factory: str, kwargs: dict[str, Any] | None = None) -> None:
        self.name = name
        self.endpoint = Endpoint(build_board(factory, kwargs))
        #: replies to advances posted and not yet waited for (a pipelined orchestrator posts
        #: the next quantum before waiting for the present one)
        self._replies: list[bytes | None] = []
        hello = _loads(self.endpoint.hello())
        self.ports: list[tuple[str, str, str]] = hello[1][1]
        self.alive = True

    @property
    def board(self) -> Board:
        """The board object itself (in-process only: for debugging, never for routing)."""
        return self.endpoint.board

    def post_advance(self, start_ns: int, until_ns: int, inputs: list[Record]) -> None:
        self._replies.append(self.endpoint.handle(_dumps((OP_ADVANCE, start_ns, until_ns,
                                                          inputs))))

    def wait_advance(self) -> tuple[list[Record], int | None]:
        raw = self._replies.pop(0)
        reply: tuple = _loads(raw) if raw is not None else (R_ERROR, "board stopped")
        if reply[0] == R_OK:
            return reply[1], reply[2]
        self.alive = False
        raise BoardDied(self.name, reply[1])

    def is_alive(self) -> bool:
        return self.alive

    def call(self, method: str, *args: Any) -> Any:
        reply = _loads(self.endpoint.handle(_dumps((OP_CALL, method, args))))  # type: ignore
        if reply[0] == R_RESULT:
            return reply[1]
        raise RuntimeError(f"board {self.name}: {method} failed:\n{reply[1]}")

    def close(self, timeout_s: float = 0.0) -> None:
        if self.alive:
            self.endpoint.handle(_dumps((OP_STOP,)))
        self.alive = False
