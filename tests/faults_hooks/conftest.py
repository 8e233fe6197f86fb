"""A booted Pixhawk 1 for the fault hooks' system tests."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import pytest

from hil.faults import get_kind  # importing the package registers every kind
from hil.system import SystemConfig, build_system

S = 1_000_000_000
MS = 1_000_000


@dataclass
class Rig:
    orch: Any
    dev: dict[str, Any]

    def start(self, name: str, target: str = "", **params: Any) -> Any:
        kind = get_kind(name)
        p = kind.check(target, params)
        return kind.start(self, target, p, self.orch.t_ns)

    def stop(self, name: str, target: str, token: Any, **params: Any) -> None:
        kind = get_kind(name)
        kind.stop(self, target, kind.check(target, params), self.orch.t_ns, token)

    def run_s(self, seconds: float) -> None:
        self.orch.run(duration_ns=int(seconds * S))

    def run_until(self, cond, timeout_s: float, step_s: float = 0.01) -> float:
        """Run until cond() holds; returns the virtual time (s) it took."""
        t0 = self.orch.t_ns
        while not cond():
            if self.orch.t_ns - t0 > timeout_s * S:
                raise AssertionError(f"condition not met within {timeout_s} s")
            self.run_s(step_s)
        return (self.orch.t_ns - t0) / S

    def io_flags(self) -> list[str]:
        return self.orch.call("io", "status")["flag_names"]

    def dmesg(self) -> list[str]:
        return [m[3] for m in self.orch.call("fmu", "dmesg")]


@pytest.fixture
def rig(tmp_path):
    orch, dev = build_system(SystemConfig(seed=7, out_dir=str(tmp_path), gcs=True,
                                          params={"EKF2_MAG_DECL": 2.6}))
    orch.start()
    r = Rig(orch, dev)
    try:
        dev["gcs"].attach(orch)
        dev["gcs"].wait_heartbeat(timeout_s=10)
        r.run_until(lambda: "FMU_OK" in r.io_flags()
                    and orch.call("fmu", "topic", "px4io_status") is not None, timeout_s=5)
        yield r
    finally:
        orch.close()
