"""Speed of the world model alone (no boards): simulated seconds per wall second.

``bench_rtf_jsbsim_only()`` is the headline number: the F450 world (JSBSim + ESCs + battery)
at 1 kHz, hovering at constant PWM, median of 3 runs of 5 simulated seconds. Two companions
bracket it: the bare ``FGFDMExec.run()`` loop (the floor) and the world with ``truth()`` read
every step (what the lockstep loop pays when a board samples truth each step).

Run: ``.venv/bin/python bench/bench_world.py``
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from hil.world import World  # noqa: E402

HOVER_PWM_US = 1507.0  # F450 on a full 3S pack (found by tests/hil/test_world.py bisection)
SIM_S = 5.0
RUNS = 3


def _hovering_world(rate_hz: int) -> World:
    w = World(seed=0, rate_hz=rate_hz, agl_m=100.0)
    w.set_motor_pwm_us([1000.0] * 4)
    w.step(int(0.15 * rate_hz))  # arm the ESCs
    w.set_motor_pwm_us([HOVER_PWM_US] * 4)
    w.step(int(0.3 * rate_hz))  # spin up
    return w


def _median_rtf(run_once) -> float:
    return statistics.median(run_once() for _ in range(RUNS))


def bench_rtf_jsbsim_only(rate_hz: int = 1000, sim_s: float = SIM_S) -> float:
    """World.step() only (JSBSim F450 + ESCs + battery), hover; sim s per wall s."""

    def once() -> float:
        w = _hovering_world(rate_hz)
        n = round(sim_s * rate_hz)
        t0 = time.perf_counter()
        w.step(n)
        return sim_s / (time.perf_counter() - t0)

    return _median_rtf(once)


def bench_rtf_fdm_raw(rate_hz: int = 1000, sim_s: float = SIM_S) -> float:
    """Bare FGFDMExec.run() loop on the same hovering vehicle (throttles held)."""

    def once() -> float:
        w = _hovering_world(rate_hz)
        run = w.fdm.run
        n = round(sim_s * rate_hz)
        t0 = time.perf_counter()
        for _ in range(n):
            run()
        return sim_s / (time.perf_counter() - t0)

    return _median_rtf(once)


def bench_rtf_world_with_truth(rate_hz: int = 1000, sim_s: float = SIM_S) -> float:
    """World.step() plus truth() every step."""

    def once() -> float:
        w = _hovering_world(rate_hz)
        step = w.step
        truth = w.truth
        n = round(sim_s * rate_hz)
        t0 = time.perf_counter()
        for _ in range(n):
            step()
            truth()
        return sim_s / (time.perf_counter() - t0)

    return _median_rtf(once)


def main() -> None:
    print(f"rtf_jsbsim_only       {bench_rtf_jsbsim_only():7.1f}  (World.step, F450, 1 kHz, hover)")
    print(f"rtf_fdm_raw           {bench_rtf_fdm_raw():7.1f}  (FGFDMExec.run only)")
    print(f"rtf_world_with_truth  {bench_rtf_world_with_truth():7.1f}  (World.step + truth())")


if __name__ == "__main__":
    main()
