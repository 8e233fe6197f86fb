"""CPU placement (``Orchestrator(isolate=...)``, :class:`hil.cpu_plan.CpuPlan`): one board
gets a CPU of its own, the orchestrator and the other boards share the rest, waiters spin
instead of blocking, and the orchestrator gets its CPUs back when it closes."""

import os

import pytest

from board.wiring import uart_link
from hil.cpu_plan import CpuPlan
from hil.ipc import SpinPolicy
from hil.orchestrator import PINNED_SPIN_US, BoardSpec, Orchestrator

MS = 1_000_000


def _probes():
    sends = [(t * 250_000, bytes([t])) for t in range(1, 12)]
    return {"fmu": BoardSpec("board.stock:UartProbeBoard", {"name": "fmu", "sends": sends}),
            "io": BoardSpec("board.stock:UartProbeBoard", {"name": "io", "sends": []})}


def test_plan_gives_the_last_cpu_to_the_board_and_the_rest_to_everybody_else():
    plan = CpuPlan.make("fmu", cpus={0, 1})
    assert plan is not None
    assert plan.cpus_for("fmu") == {1} and plan.cpus_for("io") == {0}
    plan = CpuPlan.make("fmu", cpus={2, 5, 7, 3})
    assert plan is not None
    assert plan.cpus_for("fmu") == {7} and plan.cpus_for("io") == {2, 3, 5}
    assert plan.describe() == "fmu on CPU 7, the rest on 2,3,5"


def test_one_cpu_means_no_plan_and_says_why():
    said = []
    assert CpuPlan.make("fmu", log=said.append, cpus={3}) is None
    assert said == ["hil: CPUs not pinned (one CPU available)"]


def test_isolating_an_unknown_board_is_refused():
    with pytest.raises(ValueError, match="isolate: no board 'gps'"):
        Orchestrator(_probes(), isolate="gps")


def test_process_boards_are_pinned_and_the_orchestrator_restored_on_close():
    before = os.sched_getaffinity(0)
    orch = Orchestrator(_probes(), uart_link(("fmu", "uart"), ("io", "uart")), quantum_ns=MS,
                        pipeline=True, isolate="fmu")
    with orch:
        plan = orch.cpu_plan
        if len(before) < 2:  # nothing to split: the run goes on unpinned
            assert plan is None
        else:
            assert plan is not None
            assert os.sched_getaffinity(orch.handles["fmu"].pid) == plan.cpus_for("fmu")
            assert os.sched_getaffinity(orch.handles["io"].pid) == plan.cpus_for("io")
            assert os.sched_getaffinity(0) == plan.cpus_for("io")
            assert plan.cpus_for("fmu").isdisjoint(plan.cpus_for("io"))
            # Unpaced and pinned: every waiter spins (adaptively) instead of blocking.
            for handle in orch.handles.values():
                assert handle._ch.spin.max_us == PINNED_SPIN_US
        orch.run(duration_ns=4 * MS)
        got = orch.call("io", "received")
    assert [b for _, b in got] == list(range(1, 12))[:len(got)] and got  # bytes still cross
    assert os.sched_getaffinity(0) == before
    assert orch.cpu_plan is None


def test_paced_or_unpinned_runs_keep_the_default_spin_policy():
    default = SpinPolicy().max_us
    for kw in ({"isolate": "fmu", "speed": 50.0}, {}):
        with Orchestrator(_probes(), quantum_ns=MS, **kw) as orch:
            for handle in orch.handles.values():
                assert handle._ch.spin.max_us == default


def test_a_rebooted_board_gets_its_cpus_again():
    with Orchestrator(_probes(), quantum_ns=MS, pipeline=True, isolate="fmu") as orch:
        orch.run(duration_ns=2 * MS)
        old_pid = orch.handles["fmu"].pid
        orch._restart("fmu")  # what a "reboot" record from the board leads to
        new_pid = orch.handles["fmu"].pid
        assert new_pid != old_pid
        plan = orch.cpu_plan
        if plan is None:
            assert len(os.sched_getaffinity(0)) < 2
        else:
            assert os.sched_getaffinity(new_pid) == plan.cpus_for("fmu")
            assert orch.handles["fmu"]._ch.spin.max_us == PINNED_SPIN_US
        orch.run(duration_ns=2 * MS)  # and it runs on
        assert orch.reboots == {"fmu": 1}
