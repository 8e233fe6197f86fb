"""How expectations are judged over samples in virtual time (no rig needed)."""

from __future__ import annotations

from hil.scenarios.engine import _State
from hil.scenarios.model import scenario_from_dict


def _judge(expect: dict, samples: list[tuple[float, dict]], events: dict[str, float],
           end: float):
    sc = scenario_from_dict({"events": {e: "armed" for e in events if e != "start"},
                             "expect": [expect]})
    st = _State(sc.expect[0])
    for t, values in samples:
        st.step(t, {"start": 0.0, **{k: v for k, v in events.items() if v <= t}}, values.get)
    st.finish(end, {"start": 0.0, **{k: v for k, v in events.items() if v <= end}})
    return st.res


def _series(t0, t1, dt, fn):
    n = round((t1 - t0) / dt)
    return [(round(t0 + i * dt, 6), fn(round(t0 + i * dt, 6))) for i in range(n + 1)]


def test_within_is_met_at_the_first_sample_after_its_event():
    s = _series(0, 3, 0.02, lambda t: {"rc_lost": t >= 1.23})
    r = _judge({"within": 0.3, "of": "ev", "that": "rc_lost"}, s, {"ev": 1.0}, 3.0)
    assert r.verdict == "pass" and r.t_met_s == 1.24 and r.latency_s == 0.24


def test_within_fails_at_its_deadline():
    s = _series(0, 3, 0.02, lambda t: {"rc_lost": t >= 1.5})
    r = _judge({"within": 0.3, "of": "ev", "that": "rc_lost"}, s, {"ev": 1.0}, 3.0)
    assert r.verdict == "fail" and r.t_broken_s == 1.3 and "within 0.3 s" in r.reason


def test_an_event_that_never_happens_fails_the_expectation():
    s = _series(0, 1, 0.02, lambda t: {"rc_lost": True})
    r = _judge({"within": 0.3, "of": "ev", "that": "rc_lost"}, s, {"ev": 99.0}, 1.0)
    assert r.verdict == "fail" and "never happened" in r.reason


def test_never_and_always_with_windows():
    s = _series(0, 3, 0.02, lambda t: {"armed": 1.0 <= t < 2.0})
    assert _judge({"never": "armed", "for": 0.9}, s, {}, 3.0).verdict == "pass"
    r = _judge({"never": "armed"}, s, {}, 3.0)
    assert r.verdict == "fail" and r.t_broken_s == 1.0
    r = _judge({"always": "armed", "from": "ev", "for": 0.5}, s, {"ev": 1.2}, 3.0)
    assert r.verdict == "pass"
    r = _judge({"always": "armed", "from": "ev"}, s, {"ev": 1.2}, 3.0)
    assert r.verdict == "fail" and r.t_broken_s == 2.0


def test_eventually_fails_if_never_true():
    s = _series(0, 2, 0.02, lambda t: {"armed": False})
    r = _judge({"eventually": "armed"}, s, {}, 2.0)
    assert r.verdict == "fail" and r.reason == "never became true"
