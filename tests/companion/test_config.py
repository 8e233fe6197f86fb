"""How a user asks for the companion: hil run/fly options, the scenario keys, the wiring."""

import pytest

from board.wiring import COMPANION_WIRES
from hil.cli import build_parser
from hil.scenarios.model import ScenarioError, scenario_from_dict


def test_cli_options():
    p = build_parser()
    a = p.parse_args(["run", "--companion-att"])
    assert a.companion_att and not a.companion
    a = p.parse_args(["fly", "--ros"])
    assert a.ros and not a.companion
    assert p.parse_args(["shell", "--board", "companion"]).board == "companion"
    assert p.parse_args(["shell"]).board == "fmu"
    with pytest.raises(SystemExit):
        p.parse_args(["shell", "--board", "io"])


def test_wiring_is_telem2_both_ways():
    assert [(w.src, w.dst) for w in COMPANION_WIRES] == [
        (("fmu", "telem2"), ("companion", "telem2")),
        (("companion", "telem2"), ("fmu", "telem2"))]


def _doc(**extra):
    return {"name": "c", "expect": [{"never": "estimator_fault"}], **extra}


def test_scenario_keys():
    sc = scenario_from_dict(_doc(companion=True, companion_att=True))
    assert sc.companion and sc.companion_att
    sc = scenario_from_dict(_doc())
    assert not sc.companion and not sc.companion_att
    with pytest.raises(ScenarioError, match="companion: true or false"):
        scenario_from_dict(_doc(companion="yes"))
