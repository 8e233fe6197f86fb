"""The budget of the property-based tests that feed outside input to a decoder or parser.

Every test that fuzzes an entry point for outside bytes or text (RC decoders, the PX4IO
protocol, MAVLink, BSON and the FRAM parameter store, the shell, the scenario loader, ...)
is decorated with ``@fuzz(examples)``. That marks it ``fuzz`` and gives hypothesis a budget:

- in ``make test`` each target tries ``examples`` inputs, so that all of them together take
  under a minute of CPU (42 s for 45 targets on 2026-11-26); the inputs are derandomized (the same every run), so a failure in CI
  is the failure you get at your desk;
- ``make fuzz`` (the long run, ``HIL_FUZZ_SCALE`` set) multiplies every budget by that scale,
  draws fresh random inputs (hypothesis keeps failures in ``.hypothesis/`` and tries them first
  next time), and prints hypothesis's statistics: how many inputs each target tried, how many
  the strategy rejected, and how long it took.

No deadline: the boards are slow to build, and a slow example is not a failure. Health checks
about slow or large data are off for the same reason; the others (a strategy that filters out
everything, say) stay on.
"""

from __future__ import annotations

import os
from typing import Callable, TypeVar

import pytest
from hypothesis import HealthCheck, settings

__all__ = ["LONG_RUN", "SCALE", "fuzz"]

#: The long run's multiplier (``make fuzz`` sets it); unset in ``make test``.
LONG_RUN: bool = "HIL_FUZZ_SCALE" in os.environ
SCALE: float = float(os.environ.get("HIL_FUZZ_SCALE", "1"))

T = TypeVar("T", bound=Callable[..., object])


def fuzz(examples: int) -> Callable[[T], T]:
    """Mark a hypothesis test as a fuzz target with a budget of ``examples`` inputs per run."""
    if examples < 1:
        raise ValueError("a fuzz target needs at least one example")

    def wrap(test: T) -> T:
        budget = settings(
            max_examples=max(1, round(examples * SCALE)),
            deadline=None,
            derandomize=not LONG_RUN,
            suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                   HealthCheck.large_base_example,
                                   HealthCheck.function_scoped_fixture],
        )
        return pytest.mark.fuzz(budget(test))  # type: ignore[no-any-return]

    return wrap
