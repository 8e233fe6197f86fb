"""The shipped scenario library: every catalogue fault is covered by a scenario, and every
scenario gives the outcome PX4 defines (a scenario with a ``known_failure`` must fail, strictly:
once the stack is fixed the test says so)."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.faults import CATALOGUE
from hil.scenarios import format_table, library_scenarios, load_scenario, run_scenario

FILES = library_scenarios()
SCENARIOS = {p.stem: load_scenario(str(p)) for p in FILES}
COVERED = {k for sc in SCENARIOS.values() for k in sc.fault_kinds()}


@pytest.mark.parametrize("kind", sorted(CATALOGUE))
def test_every_catalogue_fault_has_a_library_scenario(kind):
    assert kind in COVERED, (
        f"fault kind {kind!r} ({CATALOGUE[kind].level}) has no scenario in "
        f"hil/scenarios/library/: add one with the outcome PX4 defines for it")


def test_library_scenarios_are_documented():
    for name, sc in SCENARIOS.items():
        assert len(sc.doc) > 60 and sc.reference, name
        assert Path(sc.source).stem == sc.name, name


def _params(path: Path):
    sc = SCENARIOS[path.stem]
    marks = [pytest.mark.slow]
    if sc.known_failure:
        marks.append(pytest.mark.xfail(reason=sc.known_failure, strict=True))
    return pytest.param(path, id=path.stem, marks=marks)


@pytest.mark.parametrize("path", [_params(p) for p in FILES])
def test_library_scenario_passes(path, tmp_path):
    result = run_scenario(SCENARIOS[path.stem], out_dir=str(tmp_path))
    print(format_table(result))
    assert result.passed, format_table(result)
    assert result.log and Path(result.log).stat().st_size > 0
    assert Path(result.trace).stat().st_size > 0
