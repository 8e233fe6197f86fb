"""Scenarios: a rig, a timeline of pilot, GCS and fault actions, and expectations judged in
virtual time (docs/faults.md).

    sc = load_scenario("hil/scenarios/library/rc_loss_return.yaml")
    result = run_scenario(sc, seed=2, out_dir="out/rc_loss")
    assert result.passed, format_table(result)
"""

from __future__ import annotations

from pathlib import Path

from hil.scenarios.engine import ExpectationResult, ScenarioResult, run_scenario
from hil.scenarios.model import Scenario, ScenarioError, load_scenario, scenario_from_dict
from hil.scenarios.report import format_table

__all__ = ["LIBRARY", "ExpectationResult", "Scenario", "ScenarioError", "ScenarioResult",
           "format_table", "library_scenarios", "load_scenario", "run_scenario",
           "scenario_from_dict"]

#: the shipped scenario library
LIBRARY = Path(__file__).parent / "library"


def library_scenarios() -> list[Path]:
    """The shipped scenario files, sorted by name."""
    return sorted(LIBRARY.glob("*.yaml"))
