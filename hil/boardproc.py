"""A board in its own OS process, driven through the shared-memory channel of :mod:`hil.ipc`.

:class:`ProcessHandle` is the orchestrator's side; :func:`board_process_main` is the child.
Both sides speak the endpoint messages of :mod:`board.endpoint`, exactly as
:class:`board.endpoint.LocalHandle` does in one process, so tests can run a system either way.

Process hygiene, because a simulator that leaves processes behind is not one anybody keeps:

* the child ignores SIGINT (Ctrl-C in a terminal reaches the whole process group; the
  orchestrator decides how to stop);
* the child asks Linux to kill it if the orchestrator dies (``PR_SET_PDEATHSIG``), and the
  channel notices a vanished parent anyway;
* :meth:`ProcessHandle.close` asks nicely, then terminates, then kills.
"""

from __future__ import annotations

import ctypes
import marshal
import multiprocessing
import os
import signal
import sys
import traceback
from typing import Any

from board.endpoint import OP_ADVANCE, OP_CALL, OP_STOP, R_ERROR, R_OK, R_RESULT, BoardDied
from board.endpoint import Endpoint, build_board
from hil.ipc import ChannelClosed, ChannelPair, ChannelSpec, ChannelTimeout, PeerDied, SpinPolicy

__all__ = ["STATS_ENV", "OffsetHandle", "ProcessHandle", "board_process_main", "resolve_kwargs"]

_dumps = marshal.dumps
_loads = marshal.loads

#: Environment variable naming a folder: each board process then times every request it
#: serves and writes the times there when it ends (see ``_serve``).
STATS_ENV = "HIL_BOARD_STATS"

#: Ring size per direction; a quantum's traffic is far smaller, larger messages still stream.
CHANNEL_CAPACITY = 1 << 18


def _die_with_parent() -> None:
    if not sys.platform.startswith("linux"):
        return
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        PR_SET_PDEATHSIG = 1
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):
        pass


def resolve_kwargs(kwargs: dict[str, Any]) -> dict[str, Any]:
    """Turn plain-data stand-ins into host objects a board may be given.

    ``host_clock="perf_counter"`` becomes :func:`time.perf_counter`: only hil/ hands the
    wall clock to a board (for ``top``'s host-time column), never the board itself.
    """
    out = dict(kwargs)
    if out.get("host_clock") == "perf_counter":
        import time

        out["host_clock"] = time.perf_counter
    return out


def board_process_main(spec: ChannelSpec, name: str, factory: str,
                       kwargs: dict[str, Any]) -> None:
    """Body of a board process: build the board, say hello, then serve requests."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _die_with_parent()
    ch = spec.attach()
    try:
        try:
            endpoint = Endpoint(build_board(factory, resolve_kwargs(kwargs)))
        except Exception:
            ch.send(_dumps((R_ERROR, f"building board {name} with {factory} failed:\n"
                                     f"{traceback.format_exc()}")))
            return
        ch.send(endpoint.hello())
        stats_dir = os.environ.get(STATS_ENV)
        _serve(ch, endpoint, os.path.join(stats_dir, f"{name}-{os.getpid()}.json")
               if stats_dir else None)
    finally:
        ch.close()


def _serve(ch: Any, endpoint: Endpoint, stats_path: str | None) -> None:
    """Answer requests until told to stop, the orchestrator goes, or the firmware raises (this
    chip is then dead, and its process ends). With ``stats_path`` (``STATS_ENV``, for
    bench.board_busy), also time each request on the host clock, how long the board waited
    for it and how long it took to handle, and write the times there as JSON at the end."""
    import time

    timed = stats_path is not None
    clock = time.perf_counter
    cpu_clock = time.thread_time  # host CPU time: what the wall time was, minus steal
    waits: list[float] = []
    busy: list[float] = []
    busy_cpu: list[float] = []
    try:
        while True:
            t0 = clock() if timed else 0.0
            try:
                request = ch.recv()
            except (ChannelClosed, PeerDied):
                return
            if timed:
                t1 = clock()
                c1 = cpu_clock()
                reply = endpoint.handle(request)
                busy_cpu.append(cpu_clock() - c1)
                busy.append(clock() - t1)
                waits.append(t1 - t0)
            else:
                reply = endpoint.handle(request)
            if reply is None:
                return
            ch.send(reply)
            if not endpoint.alive:
                return
    finally:
        if stats_path is not None:
            import json

            with open(stats_path, "w") as f:
                json.dump({"wait_s": waits, "busy_s": busy, "busy_cpu_s": busy_cpu}, f)


class ProcessHandle:
    """The orchestrator's handle on a board process (same interface as ``LocalHandle``)."""

    def __init__(self, name: str, factory: str, kwargs: dict[str, Any] | None = None,
                 start_method: str = "spawn", reply_timeout_s: float | None = 120.0,
                 spin: SpinPolicy | None = None) -> None:
        self.name = name
        self.reply_timeout_s = reply_timeout_s
        ctx = multiprocessing.get_context(start_method)
        # ``spin``: how both ends wait for a message (hil.ipc.SpinPolicy; None: its default)
        self._ch, spec = ChannelPair.create(capacity=CHANNEL_CAPACITY, ctx=ctx, spin=spin,
                                            child_spin=spin)
        self.proc = ctx.Process(target=board_process_main, name=f"hil-{name}",
                                args=(spec, name, factory, dict(kwargs or {})), daemon=True)
        self.proc.start()
        self._ch.watch(self.proc)
        self.alive = True
        hello = self._recv("start-up", timeout_s=300.0)
        if hello[0] != R_RESULT:
            self.alive = False
            self.close()
            raise BoardDied(name, hello[1])
        self.ports: list[tuple[str, str, str]] = hello[1][1]

    @property
    def pid(self) -> int | None:
        return self.proc.pid

    def _recv(self, what: str, timeout_s: float | None = None) -> tuple:
        try:
            return _loads(self._ch.recv(timeout_s=timeout_s or self.reply_timeout_s))
        except (PeerDied, ChannelClosed):
            self.alive = False
            self.proc.join(timeout=1.0)
            code = self.proc.exitcode
            how = (f"killed by signal {-code}" if code is not None and code < 0
                   else f"exit code {code}")
            raise BoardDied(self.name, f"process {self.proc.pid} ended during {what} ({how})"
                            ) from None
        except ChannelTimeout:
            self.alive = False
            raise BoardDied(self.name, f"no reply within {self.reply_timeout_s} s during "
                                       f"{what} (hung?)") from None

    def post_advance(self, start_ns: int, until_ns: int, inputs: list) -> None:
        try:
            self._ch.send(_dumps((OP_ADVANCE, start_ns, until_ns, inputs)))
        except (PeerDied, ChannelClosed):
            self.alive = False  # wait_advance reports it with the exit status

    def wait_advance(self) -> tuple[list, int | None]:
        reply = self._recv("advance")
        if reply[0] == R_OK:
            return reply[1], reply[2]
        self.alive = False
        raise BoardDied(self.name, reply[1])

    def call(self, method: str, *args: Any) -> Any:
        self._ch.send(_dumps((OP_CALL, method, args)))
        reply = self._recv(f"call {method}")
        if reply[0] == R_RESULT:
            return reply[1]
        raise RuntimeError(f"board {self.name}: {method} failed:\n{reply[1]}")

    def is_alive(self) -> bool:
        return self.alive and self.proc.is_alive()

    def kill(self) -> None:
        """Kill the process abruptly (a test or an injected 'board dead' fault)."""
        if self.proc.is_alive():
            os.kill(self.proc.pid, signal.SIGKILL)

    def close(self, timeout_s: float = 2.0) -> None:
        """Stop the board process: ask, then terminate, then kill. Idempotent."""
        if self.alive and self.proc.is_alive():
            try:
                self._ch.send(_dumps((OP_STOP,)), timeout_s=timeout_s)
            except Exception:
                pass
        self.alive = False
        self.proc.join(timeout=timeout_s)
        if self.proc.is_alive():
            self.proc.terminate()
            self.proc.join(timeout=timeout_s)
        if self.proc.is_alive():
            self.proc.kill()
            self.proc.join(timeout=timeout_s)
        self._ch.close()


class OffsetHandle:
    """A rebooted board: its clock started at ``offset_ns`` of the orchestrator's time."""

    def __init__(self, inner: Any, offset_ns: int) -> None:
        self.inner = inner
        self.offset = offset_ns
        self.name = inner.name
        self.ports = inner.ports

    def post_advance(self, start_ns: int, until_ns: int, inputs: list) -> None:
        off = self.offset
        self.inner.post_advance(start_ns - off, until_ns - off,
                                [(p, max(t - off, 0), v) for p, t, v in inputs])

    def wait_advance(self) -> tuple[list, int | None]:
        out, nxt = self.inner.wait_advance()
        off = self.offset
        return [(p, t + off, v) for p, t, v in out], (None if nxt is None else nxt + off)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)
