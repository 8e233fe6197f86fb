"""Lockstep traces: writing (:class:`TraceWriter`, for the orchestrator), reading and replaying.

A trace holds, per board and quantum, the records that went in and came out, and the control
calls each board received. Replaying a board rebuilds it from the factory in the header and
feeds it the recorded inputs and calls, in order;
since a board is deterministic, it must produce the recorded outputs again. That makes a trace
both a debugging aid (run one board alone under a debugger with the exact inputs of a failing
system run) and a regression oracle.
"""

from __future__ import annotations

import marshal
from dataclasses import dataclass
from typing import Any, Iterator

from board.endpoint import LocalHandle

__all__ = ["TraceWriter", "read_trace", "replay_board", "Mismatch", "TraceError"]


class TraceError(ValueError):
    pass


@dataclass(frozen=True)
class Mismatch:
    board: str
    until_ns: int
    recorded: list
    replayed: list


class TraceWriter:
    """Records every inter-process message (stamped records per board per quantum).

    The file is a sequence of marshalled tuples: a header
    ``("fmu-hil-trace", 2, quantum_ns, {board: (factory, kwargs)})``, then one
    ``(board, until_ns, inputs, outputs)`` per board per quantum and one
    ``(board, None, method, args)`` per control call (shell commands, parameters, faults), in
    the order the board saw them. ``hil.trace.replay_board`` rebuilds a board and feeds it the
    recorded inputs and calls to reproduce its outputs.
    """

    VERSION = 2

    def __init__(self, path: str, quantum_ns: int, boards: dict[str, Any]) -> None:
        """``boards``: name -> spec with ``factory`` and ``kwargs`` (hil.orchestrator.BoardSpec)."""
        self._f = open(path, "wb")  # noqa: SIM115 - closed by close()
        header = {name: (s.factory, s.kwargs) for name, s in boards.items()}
        marshal.dump(("fmu-hil-trace", self.VERSION, quantum_ns, header), self._f)

    def write(self, board: str, until_ns: int, inputs: list, outputs: list) -> None:
        marshal.dump((board, until_ns, inputs, outputs), self._f)

    def call(self, board: str, method: str, args: tuple) -> None:
        marshal.dump((board, None, method, args), self._f)

    def close(self) -> None:
        self._f.close()


def read_trace(path: str) -> tuple[dict[str, Any], Iterator[tuple[str, Any, Any, Any]]]:
    """Return (header, iterator of records): ``(board, until_ns, inputs, outputs)`` per quantum
    and, from version 2, ``(board, None, method, args)`` per control call."""
    f = open(path, "rb")  # noqa: SIM115 - closed by the generator
    try:
        header = marshal.load(f)
    except (EOFError, ValueError, TypeError) as exc:
        f.close()
        raise TraceError(f"{path}: not an fmu-hil trace ({exc})") from None
    if not (isinstance(header, tuple) and len(header) == 4 and header[0] == "fmu-hil-trace"):
        f.close()
        raise TraceError(f"{path}: not an fmu-hil trace (bad header)")
    if header[1] not in (1, TraceWriter.VERSION):
        f.close()
        raise TraceError(f"{path}: trace version {header[1]} is not supported")
    info = {"quantum_ns": header[2], "boards": header[3]}

    def records() -> Iterator[tuple[str, Any, Any, Any]]:
        with f:
            while True:
                try:
                    rec = marshal.load(f)
                except EOFError:
                    return
                except (ValueError, TypeError) as exc:
                    raise TraceError(f"{path}: corrupt record ({exc})") from None
                yield rec

    return info, records()


def replay_board(path: str, board: str, max_mismatches: int = 10,
                 kwargs: dict[str, Any] | None = None) -> tuple[int, list[Mismatch]]:
    """Replay one board of a trace (its quanta and control calls, in order); returns (quanta
    replayed, mismatches found).

    A board's persistent storage (its FRAM image, its SD card) is not in the trace: the board
    is built with the recorded factory arguments, updated with ``kwargs``, and the files they
    name must be as they were when the recording started (a fresh FRAM for a first boot).
    """
    info, records = read_trace(path)
    if board not in info["boards"]:
        raise TraceError(f"{path}: no board {board!r} (boards: {', '.join(info['boards'])})")
    factory, recorded_kwargs = info["boards"][board]
    quantum = info["quantum_ns"]
    handle = LocalHandle(board, factory, {**recorded_kwargs, **(kwargs or {})})
    quanta = 0
    mismatches: list[Mismatch] = []
    try:
        for name, until_ns, inputs, outputs in records:
            if name != board:
                continue
            if until_ns is None:  # a control call (shell command, parameter, fault)
                method, args = inputs, outputs
                try:
                    handle.call(method, *args)
                except RuntimeError:
                    pass  # a refused call (bad argument) is refused again; the board runs on
                continue
            handle.post_advance(until_ns - quantum, until_ns, inputs)
            got, _ = handle.wait_advance()
            quanta += 1
            if got != outputs:
                mismatches.append(Mismatch(board, until_ns, outputs, got))
                if len(mismatches) >= max_mismatches:
                    break
    finally:
        handle.close()
    return quanta, mismatches
