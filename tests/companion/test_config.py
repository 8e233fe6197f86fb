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


def test_cli_refuses_what_cannot_work_with_the_command_s_own_usage(capsys):
    from hil.cli import main

    # the attitude law on the companion is the multicopter's
    assert main(["run", "--companion-att", "--airframe", "plane"]) == 2
    assert "airframe 2100 (standard_plane) is a fixedwing" in capsys.readouterr().err
    # a misspelt option: the subcommand's usage, not the top level's
    with pytest.raises(SystemExit) as exc:
        main(["run", "--companoin"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("usage: hil run ") and "unrecognized arguments: --companoin" in err
    # hil rosnode takes its own command line, help included
    assert main(["rosnode", "--help"]) == 0
    assert "usage: hil rosnode MODULE" in capsys.readouterr().out


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
