"""cpuload from load_mon (PX4's load monitor) on the modelled CPU time, in-process on an FMU
with only its sensor drivers: 2 Hz, the load the work queues were busy, a greedy work item
(the CPU-load fault) showing in it, RAM unmodelled (NaN); and SYS_STATUS's load taken from it."""

import math

import pytest

from fmu.board import BOOT_TO_SENSORS_NS, FmuV2Board
from firmware.platform.uorb import Subscription
from firmware.system import System

S = 1_000_000_000


@pytest.fixture(scope="module")
def board():
    """The sensor drivers' FMU (no rcS, so no system of its own) with a System for load_mon."""
    b = FmuV2Board(seed=3, firmware="sensors")
    b.kernel.run(BOOT_TO_SENSORS_NS)
    b.load_system = System(b.platform, None)
    assert b.load_system.modules.start("load_mon") == 0
    return b


def _messages(board, seconds):
    """The cpuload messages published in the next ``seconds`` of virtual time."""
    sub = Subscription(board.platform.orb, "cpuload")
    sub.copy()
    out = []
    end = board.kernel.now_ns + int(seconds * S)
    while board.kernel.now_ns < end:
        board.kernel.run_for(S // 100)
        m = sub.update()
        if m is not None:
            out.append(m.copy())
    return out


def test_two_hertz_with_the_work_queues_busy_share_and_ram_not_modelled(board):
    msgs = _messages(board, 2.25)
    assert len(msgs) == 4
    stamps = [m.timestamp for m in msgs]
    assert all(b - a == 500_000 for a, b in zip(stamps, stamps[1:], strict=False))
    calm = msgs[-1].load
    assert 0.0 < calm < 0.6                      # the sensor drivers alone
    assert all(math.isnan(m.ram_usage) for m in msgs)
    wq_busy = sum(wq.busy_ns_total for wq in board.platform.wq)
    assert wq_busy > 0

    board.call("cpu_load", "wq:lp_default", 0.3, 2000)    # 0.6 ms of every 2 ms
    loaded = _messages(board, 1.5)[-1].load
    assert loaded - calm == pytest.approx(0.3, abs=0.05)
    board.call("cpu_load", "wq:lp_default", 0.0)
    after = _messages(board, 1.5)[-1].load
    assert after == pytest.approx(calm, abs=0.03)
    (line,) = board.load_system.modules.get("load_mon").status_lines()
    assert f"CPU load: {100 * after:.1f} %" in line and "RAM: not modelled" in line
