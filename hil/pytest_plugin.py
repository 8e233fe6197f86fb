"""pytest plugin for fmu-hil (registered through the ``pytest11`` entry point ``hil``).

Fixtures:

* ``hil_config`` (override it, or parametrize ``hil_vehicle`` indirectly with a dict of
  :class:`hil.system.SystemConfig` fields: ``seed``, ``params``, ``rc``, ``mode``...): what to
  build. Defaults: seed 1, S.BUS, a GCS, one process.
* ``hil_vehicle``: a booted :class:`HilVehicle` (both boards, the world, RC, GCS), closed after
  the test. Its methods act in virtual time:

    v.run(0.5)                                  # advance 0.5 virtual s
    v.wait_for("imu_primary == 1", within=1.0)  # a condition, with a virtual-time budget
    v.sticks(throttle=0.6)                      # the pilot's transmitter
    f = v.fault("sensor.absent", "mpu6000")     # any catalogue fault, now
    v.clear(f)
    v.read("nav_state")                         # any scenario observable
    v.expect("armed", within=2.0)               # wait_for that fails the test on timeout

Conditions and observables are the scenario engine's (docs/faults.md), so a test and a
scenario say the same things the same way. ``wait_for`` raises :class:`HilTimeout` (an
``AssertionError``) naming the condition and the virtual time it waited.
"""

from __future__ import annotations

from typing import Any

import pytest

__all__ = ["HilTimeout", "HilVehicle"]

NS = 1_000_000_000


class HilTimeout(AssertionError):
    """A condition did not hold within its virtual-time budget."""


class HilVehicle:
    """A running rig with helpers that speak the scenario vocabulary."""

    def __init__(self, orch: Any, dev: dict[str, Any]) -> None:
        from hil.faults import Injector
        from hil.scenarios.observables import Sampler

        self.orch = orch
        self.dev = dev
        self.injector = Injector(orch, dev).install()
        self.sampler = Sampler(orch, dev)

    @property
    def t_s(self) -> float:
        return self.orch.t_ns / NS

    def run(self, seconds: float) -> None:
        """Advance virtual time."""
        self.orch.run(duration_ns=int(round(seconds * NS)))

    def _cond(self, text: Any) -> Any:
        from hil.scenarios.model import _cond

        return _cond(text, "condition")

    def read(self, name: str) -> Any:
        """An observable now (see docs/faults.md, Observables)."""
        from hil.scenarios.observables import is_observable

        if not is_observable(name):
            raise ValueError(f"unknown observable {name!r} (see docs/faults.md)")
        self.sampler.new_sample()
        return self.sampler.read(name)

    def check(self, condition: Any) -> bool:
        self.sampler.new_sample()
        return bool(self._cond(condition)(self.sampler.read))

    def wait_for(self, condition: Any, within: float, step: float = 0.02) -> float:
        """Advance until ``condition`` holds; returns the virtual seconds it took. Raises
        :class:`HilTimeout` after ``within`` virtual seconds."""
        cond = self._cond(condition)
        t0 = self.orch.t_ns
        end = t0 + int(within * NS)
        while True:
            self.sampler.new_sample()
            if cond(self.sampler.read):
                return (self.orch.t_ns - t0) / NS
            if self.orch.t_ns >= end:
                raise HilTimeout(f"{cond.text!r} did not hold within {within:g} virtual s "
                                 f"(t = {self.t_s:.3f} s)")
            self.orch.run(until_ns=min(end, self.orch.t_ns + int(step * NS)))

    expect = wait_for

    def sticks(self, **axes: float) -> None:
        """Move the transmitter's sticks now (roll, pitch, yaw -1..1, throttle 0..1)."""
        self.dev["rc"].tx.set_sticks(self.orch.t_ns, **axes)

    def switch(self, name: str, position: int) -> None:
        self.dev["rc"].tx.set_switch(self.orch.t_ns, name, position)

    def press_safety(self, hold_s: float = 1.5) -> None:
        """Press the safety button 0.1 s from now (the switch refuses a press in the past,
        and the orchestrator's time is the start of the boards' next quantum), as
        hil/flight.py and the scenario engine do."""
        self.dev["safety"].press(self.orch.t_ns + NS // 10, hold_s=hold_s)

    @property
    def gcs(self) -> Any:
        return self.dev["gcs"]

    def fault(self, kind: str, target: str = "", duration: float | None = None,
              **params: Any) -> Any:
        """Inject a catalogue fault now; with ``duration`` it clears itself."""
        return self.injector.start(kind, target, params, duration_s=duration)

    def clear(self, active: Any) -> None:
        self.injector.stop(active)


@pytest.fixture
def hil_config() -> dict[str, Any]:
    """SystemConfig fields for ``hil_vehicle``; override this fixture in a conftest, or
    parametrize ``hil_vehicle`` indirectly with a dict merged over it."""
    return {"seed": 1, "rc": "sbus", "gcs": True, "mode": "local",
            "params": {"EKF2_MAG_DECL": 2.6}}


@pytest.fixture
def hil_vehicle(request: pytest.FixtureRequest, hil_config: dict[str, Any],
                tmp_path_factory: pytest.TempPathFactory) -> Any:
    """A booted vehicle (boards, world, RC, GCS) in virtual time; closed after the test.
    ``@pytest.mark.parametrize("hil_vehicle", [{"seed": 2}], indirect=True)`` varies it."""
    from hil.system import SystemConfig, build_system

    extra = dict(getattr(request, "param", None) or {})
    cfg = {**hil_config, **extra,
           "params": {**hil_config.get("params", {}), **extra.get("params", {})}}
    cfg.setdefault("out_dir", str(tmp_path_factory.mktemp("hil")))
    orch, dev = build_system(SystemConfig(**cfg))
    with orch:
        if "gcs" in dev:
            dev["gcs"].attach(orch)
        yield HilVehicle(orch, dev)


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "slow: end-to-end runs that take more than a few "
                                       "seconds")
