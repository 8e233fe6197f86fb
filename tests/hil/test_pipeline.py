"""Lookahead lockstep (``Orchestrator(pipeline=True)``): each board holds the next quantum
while the orchestrator waits for the present one. Records between boards arrive at most two
quanta late (stamps kept), runs stay deterministic, and calls, kills and deaths still work."""

import pytest

from board.endpoint import BoardDied
from board.wiring import uart_link
from hil.orchestrator import BoardSpec, Orchestrator
from hil.trace import read_trace, replay_board

MS = 1_000_000
BYTE_NS_1M5 = 10 * 10**9 / 1_500_000  # 8N1 at 1.5 Mbit/s


def _probes(sends, io_sends=()):
    return {"fmu": BoardSpec("board.stock:UartProbeBoard", {"name": "fmu", "sends": sends}),
            "io": BoardSpec("board.stock:UartProbeBoard",
                            {"name": "io", "sends": list(io_sends)})}


@pytest.mark.parametrize("mode", ["local", "process"])
def test_bytes_cross_boards_at_most_two_quanta_late_with_their_stamps(mode):
    burst = bytes(range(200))  # 1.33 ms of wire time
    with Orchestrator(_probes([(900_000, burst)]), uart_link(("fmu", "uart"), ("io", "uart")),
                      mode=mode, pipeline=True) as orch:
        orch.run(duration_ns=4 * MS)
        got = orch.call("io", "received")
    assert [b for _, b in got] == list(burst)
    # Written in quantum [0, 1 ms); the IO already holds [1, 2 ms) when they are routed, so
    # they come with the quantum starting at 2 ms: bytes due earlier arrive then, later ones at
    # their exact wire time (the plain lockstep delivers them from 1 ms).
    want = [max(900_000 + int((i + 1) * BYTE_NS_1M5), 2 * MS) for i in range(200)]
    assert [t for t, _ in got] == want
    assert got[0][0] == 2 * MS and got[-1][0] == 900_000 + int(200 * BYTE_NS_1M5) > 2 * MS


def test_pipelined_runs_are_identical_across_modes_and_replay(tmp_path):
    sends = [(t * 250_000, bytes([t % 256]) * (1 + t % 7)) for t in range(1, 30)]
    replies = [(t * 333_000, b"ok") for t in range(1, 20)]
    paths = {}
    received = {}
    for mode in ("local", "process"):
        path = str(tmp_path / f"{mode}.bin")
        with Orchestrator(_probes(sends, replies), uart_link(("fmu", "uart"), ("io", "uart")),
                          mode=mode, trace_path=path, pipeline=True) as orch:
            orch.run(duration_ns=12 * MS)
            received[mode] = (orch.call("io", "received"), orch.call("fmu", "received"))
        paths[mode] = path
    assert received["local"] == received["process"]
    assert received["local"][1], "the IO's replies reached the FMU"
    data = {m: open(p, "rb").read() for m, p in paths.items()}
    assert data["local"] == data["process"]
    _, records = read_trace(paths["process"])
    records = list(records)
    # No quantum is skipped in pipelined mode: 12 quanta plus the lookahead one, per board;
    # the two calls at the end are recorded after them.
    assert sorted(r[1] // MS for r in records if r[0] == "io" and r[1] is not None) == list(
        range(1, 14))
    assert [r for r in records if r[1] is None] == [("io", None, "received", ()),
                                                    ("fmu", None, "received", ())]
    for board in ("fmu", "io"):
        quanta, mismatches = replay_board(paths["process"], board)
        assert quanta == 13 and mismatches == []


def test_a_call_sees_the_board_at_most_one_quantum_ahead():
    specs = {"fmu": BoardSpec("board.stock:EmptyBoard", {"name": "fmu", "tick_us": 100}),
             "io": BoardSpec("board.stock:EmptyBoard", {"name": "io", "tick_us": 100})}
    with Orchestrator(specs, mode="local", pipeline=True) as orch:
        orch.run(duration_ns=5 * MS)
        ticks = orch.call("fmu", "ticks")
        assert 50 <= ticks <= 60           # 10 kHz: 5 ms now, 6 ms with the quantum it holds
        orch.run(duration_ns=5 * MS)       # the drained board is not advanced twice
        assert orch.call("fmu", "ticks") == ticks + 50
        assert orch.call("io", "ticks") == ticks + 50


@pytest.mark.parametrize("victim", ["io", "fmu"])
def test_a_killed_board_is_reported_and_the_other_keeps_its_pace(victim):
    messages = []
    specs = {"fmu": BoardSpec("board.stock:EmptyBoard", {"name": "fmu", "tick_us": 100}),
             "io": BoardSpec("board.stock:EmptyBoard", {"name": "io", "tick_us": 100})}
    with Orchestrator(specs, mode="process", log=messages.append, pipeline=True) as orch:
        orch.run(duration_ns=5 * MS)
        orch.kill(victim)
        orch.run(duration_ns=5 * MS)
        assert victim in orch.dead and "killed by signal 9" in orch.dead[victim]
        assert any(victim in m and "died" in m for m in messages)
        survivor = "fmu" if victim == "io" else "io"
        assert orch.call(survivor, "ticks") in (100, 110)  # 10 ms (+ the quantum it holds)
        with pytest.raises(BoardDied):
            orch.call(victim, "ticks")
