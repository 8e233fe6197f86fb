"""``HIL_BOARD_STATS``: board processes time every request they serve and leave the times in
that folder when they end; ``bench.board_busy`` summarizes them per board."""

import json

from bench.board_busy import summarize
from hil.boardproc import STATS_ENV
from hil.orchestrator import BoardSpec, Orchestrator

MS = 1_000_000


def test_board_processes_time_their_requests(tmp_path, monkeypatch):
    monkeypatch.setenv(STATS_ENV, str(tmp_path))
    boards = {n: BoardSpec("board.stock:UartProbeBoard", {"name": n, "sends": []})
              for n in ("fmu", "io")}
    with Orchestrator(boards, quantum_ns=MS, pipeline=True) as orch:
        orch.run(duration_ns=5 * MS)
        orch.call("io", "received")
    files = sorted(p.name.rsplit("-", 1)[0] for p in tmp_path.glob("*.json"))
    assert files == ["fmu", "io"]
    for path in tmp_path.glob("*.json"):
        data = json.loads(path.read_text())
        # 6 advances (5 quanta and the lookahead one), then the stop; the IO also the call
        want = 7 + (path.name.startswith("io"))
        assert len(data["busy_s"]) == len(data["wait_s"]) == want
        assert all(t >= 0.0 for t in data["busy_s"] + data["wait_s"])
    rows = {r["board"]: r for r in summarize(str(tmp_path), skip=1)}
    assert rows["fmu"]["requests"] == 6 and rows["io"]["requests"] == 7
    assert 0.0 < rows["fmu"]["busy_share"] <= 1.0
