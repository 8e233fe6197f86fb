"""Lockstep: exact arrival times across boards, determinism, traces, dead boards, pacing."""

import os
import time

import pytest

from board.endpoint import BoardDied
from board.wiring import Wire, uart_link
from hil.orchestrator import BoardSpec, Orchestrator
from hil.trace import TraceError, read_trace, replay_board

MS = 1_000_000
BYTE_NS_1M5 = 10 * 10**9 / 1_500_000  # 8N1 at 1.5 Mbit/s


def _probes(sends, io_sends=(), **kw):
    return {"fmu": BoardSpec("board.stock:UartProbeBoard", {"name": "fmu", "sends": sends, **kw}),
            "io": BoardSpec("board.stock:UartProbeBoard",
                            {"name": "io", "sends": list(io_sends), **kw})}


def _expected_arrivals(t_start, n, quantum_end):
    """A byte arrives at its wire time, or at the start of the receiver's next quantum."""
    return [max(t_start + int((i + 1) * BYTE_NS_1M5), quantum_end) for i in range(n)]


@pytest.mark.parametrize("mode", ["local", "process"])
def test_uart_bytes_cross_boards_at_exact_virtual_times(mode):
    burst = bytes(range(40))
    sends = [(900_000, burst)]
    with Orchestrator(_probes(sends), uart_link(("fmu", "uart"), ("io", "uart")),
                      mode=mode) as orch:
        orch.run(duration_ns=3 * MS)
        got = orch.call("io", "received")
    assert [b for _, b in got] == list(burst)
    # Written at 0.9 ms, inside quantum [0, 1 ms): delivered with the quantum starting at 1 ms.
    assert [t for t, _ in got] == _expected_arrivals(900_000, 40, 1 * MS)
    assert got[0][0] == 1 * MS            # the first 14 bytes were due before 1 ms: late
    assert got[15][0] == 900_000 + 106_666  # later bytes keep their exact wire time


def test_small_quantum_gives_exact_wire_time():
    # With a quantum shorter than one byte time, nothing is ever late.
    sends = [(300_000, b"\x55\xaa\x0f")]
    with Orchestrator(_probes(sends), uart_link(("fmu", "uart"), ("io", "uart")),
                      mode="local", quantum_ns=5_000) as orch:
        orch.run(duration_ns=1 * MS)
        got = orch.call("io", "received")
    assert got == [(300_000 + int((i + 1) * BYTE_NS_1M5), b) for i, b in
                   enumerate(b"\x55\xaa\x0f")]


def test_two_runs_give_identical_traces_and_replay_reproduces(tmp_path):
    sends = [(t * 250_000, bytes([t % 256]) * (1 + t % 7)) for t in range(1, 30)]
    replies = [(t * 333_000, b"ok") for t in range(1, 20)]
    paths = []
    for run in range(2):
        path = str(tmp_path / f"trace{run}.bin")
        with Orchestrator(_probes(sends, replies), uart_link(("fmu", "uart"), ("io", "uart")),
                          mode="process", trace_path=path) as orch:
            orch.run(duration_ns=10 * MS)
        paths.append(path)
    data = [open(p, "rb").read() for p in paths]
    assert data[0] == data[1]
    info, records = read_trace(paths[0])
    assert info["quantum_ns"] == MS and set(info["boards"]) == {"fmu", "io"}
    records = list(records)
    assert 10 < len(records) <= 20  # quanta in which a board had nothing due are skipped
    # A quantum is (T, T + q]: an event at T + q belongs to it; its outputs reach the other
    # board in the next quantum.
    quantum_of = lambda t: -(-t // MS)  # noqa: E731
    io_in = {quantum_of(t) + 1 for t, _ in sends}
    io_out = {quantum_of(t) for t, _ in replies}
    assert {r[1] // MS for r in records if r[0] == "io" and r[2]} == io_in
    assert {r[1] // MS for r in records if r[0] == "io" and r[3]} == io_out
    for board in ("fmu", "io"):
        quanta, mismatches = replay_board(paths[0], board)
        assert quanta == sum(1 for r in records if r[0] == board) and mismatches == []


@pytest.mark.parametrize("pipeline", [False, True])
def test_replay_repeats_control_calls_in_order(tmp_path, pipeline):
    # A control call is an input too: bytes written by a call at 2.5 ms must come out of the
    # replayed board at the same virtual time, or the replay diverges from there on.
    path = str(tmp_path / "trace.bin")
    with Orchestrator(_probes([(400_000, b"a")]), uart_link(("fmu", "uart"), ("io", "uart")),
                      mode="local", trace_path=path, pipeline=pipeline) as orch:
        orch.run(duration_ns=2 * MS + MS // 2)
        assert orch.call("fmu", "write", b"from a call") == 11
        orch.run(duration_ns=3 * MS)
    _, records = read_trace(path)
    calls = [r for r in records if r[1] is None]
    assert calls == [("fmu", None, "write", (b"from a call",))]
    for board in ("fmu", "io"):
        quanta, mismatches = replay_board(path, board)
        assert quanta > 0 and mismatches == []


def test_replay_without_the_calls_diverges(tmp_path):
    # The check above can fail: dropping the call record makes the fmu's replay differ.
    import marshal

    path, stripped = str(tmp_path / "trace.bin"), str(tmp_path / "stripped.bin")
    with Orchestrator(_probes([]), uart_link(("fmu", "uart"), ("io", "uart")), mode="local",
                      trace_path=path) as orch:
        orch.run(duration_ns=2 * MS)
        orch.call("fmu", "write", b"xyz")
        orch.run(duration_ns=2 * MS)
    with open(path, "rb") as f, open(stripped, "wb") as out:
        marshal.dump(marshal.load(f), out)
        while True:
            try:
                rec = marshal.load(f)
            except EOFError:
                break
            if rec[1] is not None:
                marshal.dump(rec, out)
    _, mismatches = replay_board(stripped, "fmu")
    assert mismatches


def test_replay_builds_the_board_with_the_given_arguments(tmp_path):
    # kwargs replace recorded factory arguments (the FMU's FRAM and SD paths, for a replay on
    # fresh storage): a probe rebuilt without its scheduled sends no longer matches its trace.
    path = str(tmp_path / "trace.bin")
    with Orchestrator(_probes([(400_000, b"abc")]), uart_link(("fmu", "uart"), ("io", "uart")),
                      mode="local", trace_path=path) as orch:
        orch.run(duration_ns=3 * MS)
    assert replay_board(path, "fmu")[1] == []
    assert replay_board(path, "fmu", kwargs={"name": "fmu"})[1] == []
    assert replay_board(path, "fmu", kwargs={"sends": []})[1]


def test_trace_reader_rejects_garbage(tmp_path):
    bad = tmp_path / "bad.bin"
    bad.write_bytes(b"not a trace at all")
    with pytest.raises(TraceError):
        read_trace(str(bad))


def test_unknown_port_in_wiring_is_a_clear_error():
    wires = [Wire(("fmu", "uart"), ("io", "no_such_port"))]
    with pytest.raises(ValueError, match="board io has no port 'no_such_port'"):
        Orchestrator(_probes([]), wires, mode="local").start()


def _pid_alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:  # a zombie is gone for our purposes
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split()[2] != "Z"
    except FileNotFoundError:
        return False


@pytest.mark.parametrize("victim", ["io", "fmu"])
def test_killed_board_is_reported_and_the_rest_keeps_running(victim):
    messages = []
    specs = {"fmu": BoardSpec("board.stock:EmptyBoard", {"name": "fmu", "tick_us": 100}),
             "io": BoardSpec("board.stock:EmptyBoard", {"name": "io", "tick_us": 100})}
    orch = Orchestrator(specs, mode="process", log=messages.append)
    with orch:
        orch.run(duration_ns=5 * MS)
        pids = {n: h.pid for n, h in orch.handles.items()}
        orch.kill(victim)
        orch.run(duration_ns=5 * MS)
        assert victim in orch.dead
        assert "killed by signal 9" in orch.dead[victim]
        assert any(victim in m and "died" in m for m in messages)
        survivor = "fmu" if victim == "io" else "io"
        assert orch.call(survivor, "ticks") == 100  # 10 ms of 10 kHz ticks, all on time
        with pytest.raises(BoardDied):
            orch.call(victim, "ticks")
    deadline = time.monotonic() + 5
    while any(_pid_alive(p) for p in pids.values()) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not any(_pid_alive(p) for p in pids.values())


def test_firmware_exception_reports_traceback():
    specs = {"fmu": BoardSpec("tests.hil.boards:CrashingBoard", {"crash_at_ns": 2_500_000})}
    messages = []
    with Orchestrator(specs, mode="process", log=messages.append) as orch:
        orch.run(duration_ns=5 * MS)
        assert "fmu" in orch.dead
        assert "ZeroDivisionError" in orch.dead["fmu"]
        assert "crash_now" in orch.dead["fmu"]


def test_dead_board_pwm_goes_low_for_the_world():
    from hil.orchestrator import Orchestrator as O

    class FakeWorld:
        def __init__(self):
            self.inputs = []

        def run_until(self, t):
            pass

        def outputs(self, until):
            return []

        def input(self, port, t, payload):
            self.inputs.append((port, t, payload))

    world = FakeWorld()
    specs = {"io": BoardSpec("tests.hil.boards:PwmBoard", {})}
    with O(specs, [Wire(("io", "pwm1"), ("world", "esc1"))], world=world, mode="process") as orch:
        orch.run(duration_ns=3 * MS)
        assert world.inputs[0][2] == (1_500_000, 20_000_000)
        orch.kill("io")
        orch.run(duration_ns=2 * MS)
    assert world.inputs[-1][0] == "esc1" and world.inputs[-1][2] == (0, 0)


@pytest.mark.slow
@pytest.mark.paced
def test_paced_mode_keeps_virtual_time_within_5_percent_of_wall_time():
    specs = {"fmu": BoardSpec("board.stock:EmptyBoard", {"tick_us": 1000}),
             "io": BoardSpec("board.stock:EmptyBoard", {"tick_us": 1000})}
    with Orchestrator(specs, mode="process", speed=1.0) as orch:
        t0 = time.perf_counter()
        orch.run(duration_ns=10_000 * MS)
        wall = time.perf_counter() - t0
    assert abs(wall - 10.0) / 10.0 < 0.05
    assert orch.t_ns == 10_000 * MS


def test_exception_in_the_orchestrator_leaves_no_board_process():
    specs = {"fmu": BoardSpec("board.stock:EmptyBoard", {"tick_us": 500}),
             "io": BoardSpec("board.stock:EmptyBoard", {"tick_us": 500})}
    orch = Orchestrator(specs, mode="process")

    def explode(o):
        if o.t_ns >= 3 * MS:
            raise RuntimeError("scenario bug")

    orch.on_quantum.append(explode)
    with pytest.raises(RuntimeError, match="scenario bug"):
        with orch:
            pids = [h.pid for h in orch.handles.values()]
            orch.run(duration_ns=10 * MS)
    deadline = time.monotonic() + 5
    while any(_pid_alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not any(_pid_alive(p) for p in pids)
