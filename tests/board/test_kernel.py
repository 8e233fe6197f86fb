"""The discrete-event kernel: exact times, tie order, cancellation, errors."""

import pytest

from board.kernel import PRIO_ISR, PRIO_THREAD, Kernel, KernelError


def test_call_at_and_later_run_at_exact_times():
    k = Kernel()
    seen = []
    k.call_at(1500, lambda: seen.append(("a", k.now_ns)))
    k.call_later(700, lambda: seen.append(("b", k.now_ns)))
    k.run(2000)
    assert seen == [("b", 700), ("a", 1500)]
    assert k.now_ns == 2000


def test_ties_ordered_by_priority_then_scheduling_order():
    k = Kernel()
    seen = []
    k.call_at(100, seen.append, "thread", priority=PRIO_THREAD)
    k.call_at(100, seen.append, "first-default")
    k.call_at(100, seen.append, "isr", priority=PRIO_ISR)
    k.call_at(100, seen.append, "second-default")
    k.call_at(99, seen.append, "earlier")
    k.run(100)
    assert seen == ["earlier", "isr", "first-default", "second-default", "thread"]


def test_event_at_until_runs_and_later_does_not():
    k = Kernel()
    seen = []
    k.call_at(1000, seen.append, 1)
    k.call_at(1001, seen.append, 2)
    k.run(1000)
    assert seen == [1]
    k.run(1001)
    assert seen == [1, 2]


def test_cancel_before_run_and_cancel_is_idempotent():
    k = Kernel()
    seen = []
    h = k.call_later(10, seen.append, "x")
    assert Kernel.pending(h)
    k.cancel(h)
    k.cancel(h)
    assert not Kernel.pending(h)
    k.run(100)
    assert seen == []
    assert k.peek_ns() is None


def test_periodic_has_no_drift_and_can_cancel_itself():
    k = Kernel()
    times = []

    def tick():
        times.append(k.now_ns)
        if len(times) == 5:
            timer.cancel()

    timer = k.call_every(333, tick, first_ns=10)
    k.run(10_000)
    assert times == [10, 343, 676, 1009, 1342]


def test_periodic_default_first_call_one_period_from_now():
    k = Kernel()
    k.run(50)
    times = []
    k.call_every(100, lambda: times.append(k.now_ns))
    k.run(360)
    assert times == [150, 250, 350]


def test_step_runs_one_event():
    k = Kernel()
    seen = []
    k.call_at(5, seen.append, 5)
    k.call_at(9, seen.append, 9)
    assert k.step()
    assert seen == [5] and k.now_ns == 5
    assert k.step()
    assert not k.step()


def test_negative_delay_and_past_time_are_errors():
    k = Kernel()
    k.run(1000)
    with pytest.raises(ValueError, match="negative delay"):
        k.call_later(-1, print)
    with pytest.raises(ValueError, match="in the past"):
        k.call_at(999, print)
    with pytest.raises(ValueError, match="in the past"):
        k.run(10)
    with pytest.raises(ValueError, match="positive"):
        k.call_every(0, print)
    with pytest.raises(TypeError):
        k.call_later(1.5, print)


def test_exception_stops_run_and_names_callback():
    k = Kernel("fmu")
    seen = []

    def broken_driver_step():
        raise ZeroDivisionError("boom")

    k.call_at(10, seen.append, "before")
    k.call_at(20, broken_driver_step)
    k.call_at(30, seen.append, "after")
    with pytest.raises(KernelError) as err:
        k.run(100)
    assert "broken_driver_step" in str(err.value)
    assert "t=20 ns" in str(err.value)
    assert err.value.t_ns == 20
    assert isinstance(err.value.__cause__, ZeroDivisionError)
    assert seen == ["before"]
    assert k.now_ns == 20
    k.run(100)  # the rest of the schedule is intact
    assert seen == ["before", "after"]


def test_stop_returns_from_run_early():
    k = Kernel()
    seen = []
    k.call_at(10, lambda: (seen.append(10), k.stop()))
    k.call_at(20, seen.append, 20)
    k.run(100)
    assert seen == [10] and k.now_ns == 10
    k.run(100)
    assert seen == [10, 20]


def test_trace_sees_every_event_in_order():
    k = Kernel()
    trace = []
    k.set_trace(lambda t, prio, seq, name: trace.append((t, name)))

    def alpha():
        k.call_later(5, beta)

    def beta():
        pass

    k.call_at(1, alpha)
    k.run(10)
    assert trace == [(1, "test_trace_sees_every_event_in_order.<locals>.alpha"),
                     (6, "test_trace_sees_every_event_in_order.<locals>.beta")]
