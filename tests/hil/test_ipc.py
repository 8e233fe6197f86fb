"""Tests of the shared-memory transport between the orchestrator and board processes."""

from __future__ import annotations

import multiprocessing
import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import pytest

from hil.ipc import (
    ChannelClosed,
    ChannelPair,
    ChannelSpec,
    ChannelTimeout,
    PeerDied,
    SpinPolicy,
    echo_server,
)
from hil.shell_client import pid_alive

REPO = Path(__file__).resolve().parents[2]
SHM = Path("/dev/shm")


def _segments() -> set[str]:
    """Channel segments this process made, or whose maker is gone (leaks). Segments of other
    live processes (another xdist worker's flight, another run) are theirs to clean up."""
    if not SHM.is_dir():
        return set()
    mine = set()
    for p in SHM.glob("hilipc_*"):
        pid = p.name.split("_")[1]
        if not pid.isdigit() or int(pid) == os.getpid() or not pid_alive(int(pid)):
            mine.add(p.name)
    return mine


# ----------------------------------------------------------------------- child bodies
def _sleeper(spec: ChannelSpec) -> None:
    """Attach and never answer (a hung or busy board)."""
    ch = spec.attach()
    ch.send(b"ready")
    time.sleep(60)


def _sender(spec: ChannelSpec, sizes: list[int]) -> None:
    """Send messages of the given sizes (byte i of message k is (k + i) % 251), then close."""
    with spec.attach() as ch:
        for k, n in enumerate(sizes):
            ch.send(_pattern(k, n))
        ch.recv()  # wait for the parent's go-ahead to close


def _pattern(k: int, n: int) -> bytes:
    return bytes((k + i) % 251 for i in range(n)) if n < 4096 else (
        bytes(range(k % 251, 251)) + bytes(range(251)) * (n // 251 + 1)
    )[:n]


# ----------------------------------------------------------------------- fixtures
@pytest.fixture
def no_leaks():
    before = _segments()
    yield
    leaked = _segments() - before
    assert not leaked, f"leaked shared memory segments: {leaked}"


def _start(target, *args, method: str = "spawn", capacity: int = 4096, **kw):
    ctx = multiprocessing.get_context(method)
    ch, spec = ChannelPair.create(capacity=capacity, ctx=ctx, **kw)
    proc = ctx.Process(target=target, args=(spec, *args), daemon=True)
    proc.start()
    ch.watch(proc)
    return ch, proc


# ----------------------------------------------------------------------- tests
@pytest.mark.parametrize("method", ["spawn", "fork"])
def test_echo_sizes_in_order(no_leaks, method: str) -> None:
    """Empty, small, exactly-fitting, wrapping and larger-than-the-ring payloads, both ways."""
    cap = 256
    ch, proc = _start(echo_server, method=method, capacity=cap)
    try:
        sizes = [0, 1, 7, 8, 9, 100, cap - 8, cap - 7, cap, 3 * cap + 5, 0, 50_000, 13, 0]
        for k, n in enumerate(sizes * 3):
            payload = _pattern(k, n)
            ch.send(payload)
            assert ch.recv(timeout_s=10) == payload, f"message {k} of {n} bytes"
    finally:
        ch.close()
        proc.join(5)
    assert proc.exitcode == 0  # the echo server saw ChannelClosed and returned


def test_many_in_flight_and_memoryview(no_leaks) -> None:
    """Several messages queued before any is read arrive intact and in order."""
    ch, proc = _start(echo_server, capacity=1 << 14)
    try:
        msgs = [_pattern(k, k * 3) for k in range(40)]  # ~2.4 KB in flight each way
        for m in msgs:
            ch.send(memoryview(bytearray(m)))
        assert [ch.recv(timeout_s=10) for _ in msgs] == msgs
    finally:
        ch.close()
        proc.join(5)


def test_child_to_parent_stream(no_leaks) -> None:
    """The child sends a burst (some larger than the ring) that the parent reads afterwards."""
    sizes = [0, 5, 1000, 4096, 20_000, 3, 0, 8]
    ch, proc = _start(_sender, sizes, capacity=1024)
    try:
        time.sleep(0.2)  # let the child run ahead and fill the ring
        for k, n in enumerate(sizes):
            assert ch.recv(timeout_s=10) == _pattern(k, n)
        ch.send(b"bye")
    finally:
        ch.close()
        proc.join(5)
    assert proc.exitcode == 0


@pytest.mark.parametrize("spin", [SpinPolicy(), SpinPolicy(max_us=0)], ids=["adaptive", "block"])
def test_many_round_trips(no_leaks, spin: SpinPolicy) -> None:
    ch, proc = _start(echo_server, capacity=512, spin=spin, child_spin=spin)
    try:
        for k in range(20_000):
            msg = k.to_bytes(4, "little") * (1 + k % 23)
            ch.send(msg)
            assert ch.recv(timeout_s=10) == msg
    finally:
        ch.close()
        proc.join(5)


def test_recv_timeout_then_still_usable(no_leaks) -> None:
    ch, proc = _start(_sleeper)
    try:
        assert ch.recv(timeout_s=10) == b"ready"
        t0 = time.monotonic()
        with pytest.raises(ChannelTimeout):
            ch.recv(timeout_s=0.2)
        assert 0.15 < time.monotonic() - t0 < 2.0
        assert isinstance(ChannelTimeout("x"), TimeoutError)
    finally:
        proc.kill()
        proc.join(5)
        ch.close()


def test_send_times_out_when_ring_stays_full(no_leaks) -> None:
    ch, proc = _start(_sleeper, capacity=256)
    try:
        assert ch.recv(timeout_s=10) == b"ready"
        with pytest.raises(ChannelTimeout):
            ch.send(b"x" * 10_000, timeout_s=0.2)
    finally:
        proc.kill()
        proc.join(5)
        ch.close()


def test_blocked_recv_reports_sigkilled_child(no_leaks) -> None:
    """A board killed with SIGKILL while the orchestrator waits: PeerDied within ~1 s."""
    ch, proc = _start(_sleeper)
    try:
        assert ch.recv(timeout_s=10) == b"ready"
        killer = threading.Timer(0.2, os.kill, (proc.pid, signal.SIGKILL))
        killer.start()
        t0 = time.monotonic()
        with pytest.raises(PeerDied):
            ch.recv(timeout_s=30)
        waited = time.monotonic() - t0
        killer.join()
        assert waited < 1.2, waited
        proc.join(5)
        assert proc.exitcode == -signal.SIGKILL
        assert not proc.is_alive()
        assert multiprocessing.active_children() == []
    finally:
        ch.close()


def test_blocked_send_reports_sigkilled_child(no_leaks) -> None:
    ch, proc = _start(_sleeper, capacity=256)
    try:
        assert ch.recv(timeout_s=10) == b"ready"
        threading.Timer(0.2, os.kill, (proc.pid, signal.SIGKILL)).start()
        with pytest.raises(PeerDied):
            ch.send(b"y" * 100_000, timeout_s=30)
    finally:
        proc.join(5)
        ch.close()


def test_name_unlinked_once_child_attached(no_leaks) -> None:
    """After the handshake nothing is left in /dev/shm, even if everyone is then killed."""
    before = _segments()
    ch, proc = _start(echo_server)
    try:
        ch.wait_attached(timeout_s=30)
        assert _segments() == before
        ch.send(b"still works")
        assert ch.recv(timeout_s=10) == b"still works"
    finally:
        ch.close()
        proc.join(5)


def test_close_is_idempotent_and_final(no_leaks) -> None:
    ch, proc = _start(echo_server)
    ch.send(b"a")
    assert ch.recv(timeout_s=10) == b"a"
    ch.close()
    ch.close()
    assert ch.closed
    with pytest.raises(ChannelClosed):
        ch.send(b"b")
    with pytest.raises(ChannelClosed):
        ch.recv(timeout_s=0.1)
    proc.join(5)
    assert proc.exitcode == 0


def test_close_before_child_attached_unlinks(no_leaks) -> None:
    ctx = multiprocessing.get_context("spawn")
    ch, _spec = ChannelPair.create(capacity=1024, ctx=ctx)
    assert len(_segments()) >= 1
    ch.close()
    ch.close()


def test_peer_close_wakes_blocked_receiver_quickly(no_leaks) -> None:
    """The child closing its end ends a blocked recv at once with ChannelClosed."""
    ch, proc = _start(_sender, [1, 2])
    try:
        assert ch.recv(timeout_s=10) == _pattern(0, 1)
        assert ch.recv(timeout_s=10) == _pattern(1, 2)
        ch.send(b"go")  # the child now closes and exits
        t0 = time.monotonic()
        with pytest.raises((ChannelClosed, PeerDied)):
            ch.recv(timeout_s=10)
        assert time.monotonic() - t0 < 1.0
    finally:
        ch.close()
        proc.join(5)


_NO_WARNINGS_SCRIPT = textwrap.dedent(
    """
    import multiprocessing, os, signal, sys, time
    sys.path.insert(0, {repo!r})
    from hil.ipc import ChannelPair, PeerDied, echo_server

    if __name__ == "__main__":
        ctx = multiprocessing.get_context("spawn")
        for kill in (False, True):
            ch, spec = ChannelPair.create(capacity=1024, ctx=ctx)
            p = ctx.Process(target=echo_server, args=(spec,))
            p.start()
            ch.watch(p)
            ch.send(b"x" * 5000)
            assert ch.recv(timeout_s=10) == b"x" * 5000
            if kill:
                os.kill(p.pid, signal.SIGKILL)
                try:
                    ch.recv(timeout_s=10)
                except PeerDied:
                    pass
            ch.close()
            p.join(5)
        print("ok")
    """
)


def test_no_resource_tracker_warnings(tmp_path: Path) -> None:
    """Run a fresh interpreter (the tracker reports leaks at its shutdown) and read its stderr."""
    script = tmp_path / "leak_check.py"
    script.write_text(_NO_WARNINGS_SCRIPT.format(repo=str(REPO)))
    before = _segments()
    res = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                         timeout=120)
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "ok"
    assert "resource_tracker" not in res.stderr and "leaked" not in res.stderr, res.stderr
    assert _segments() == before
