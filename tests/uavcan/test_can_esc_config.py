"""Choosing CAN ESCs (``SystemConfig.can_escs``, ``hil run/fly --can-escs``, scenario key
``can_escs``) and naming DroneCAN nodes (board, scenarios): the wiring moves motors 1..4 from
the IO's PWM outputs to the ESC nodes' outputs, the FMU gets the ESC nodes and PX4's
parameters, and one parser accepts the same node entries for the board and a scenario."""

from __future__ import annotations

import pytest
from hypothesis import strategies as st
from hypothesis import given

from board.wiring import PIXHAWK1, WORLD
from hil.cli import build_parser
from hil.scenarios.document import ScenarioError
from hil.scenarios.model import scenario_from_dict
from hil.system import SystemConfig, build_system
from peripherals.dronecan.spec import check_node_specs, parse_node_spec
from tests.fuzzing import fuzz


def _motor_sources(orch):
    return {w.dst[1]: w.src for w in orch.wiring if w.dst[0] == WORLD
            and w.dst[1].startswith("esc")}


def test_can_escs_wires_the_motors_to_the_esc_nodes_only(tmp_path):
    orch, _ = build_system(SystemConfig(out_dir=str(tmp_path), can_escs=True, mode="local",
                                        params={"UAVCAN_EC_MAX": 8000}))
    src = _motor_sources(orch)
    assert [src[f"esc{i}"] for i in range(1, 5)] == [("fmu", f"can_esc{i}") for i in range(1, 5)]
    assert [src[f"esc{i}"] for i in range(5, 9)] == [("io", f"pwm{i}") for i in range(5, 9)]
    # one source per motor: the IO's pwm1..4 drive nothing
    assert not [w for w in orch.wiring if w.src[0] == "io" and w.src[1] in
                ("pwm1", "pwm2", "pwm3", "pwm4")]
    fmu = orch.specs["fmu"].kwargs
    assert fmu["uavcan_nodes"] == ("esc1@11", "esc2@12", "esc3@13", "esc4@14")
    assert fmu["params"]["UAVCAN_ENABLE"] == 3 and fmu["params"]["UAVCAN_EC_MIN"] == 1884
    assert fmu["params"]["UAVCAN_EC_MAX"] == 8000  # the user's setting wins
    pwm, _ = build_system(SystemConfig(out_dir=str(tmp_path), mode="local"))
    assert _motor_sources(pwm) == {f"esc{i}": ("io", f"pwm{i}") for i in range(1, 9)}
    assert "uavcan_nodes" not in pwm.specs["fmu"].kwargs
    assert pwm.wiring == [w for w in PIXHAWK1 if not w.src[1].startswith("rc_")] + \
        [w for w in PIXHAWK1 if w.src == (WORLD, "rc_sbus")]


def test_an_esc_given_twice_is_refused(tmp_path):
    with pytest.raises(ValueError, match="ESC given twice"):
        build_system(SystemConfig(out_dir=str(tmp_path), can_escs=True, mode="local",
                                  uavcan_nodes=("esc2",)))


def test_hil_run_and_fly_take_can_escs():
    p = build_parser()
    assert p.parse_args(["run", "--can-escs"]).can_escs
    assert p.parse_args(["fly", "--can-escs"]).can_escs
    assert not p.parse_args(["run"]).can_escs


@pytest.mark.parametrize("spec,parsed", [
    (125, ("", 125)), ("gnss", ("gnss", 0)), ("mag@21", ("mag", 21)),
    ("esc1@11", ("esc1", 11)), ("esc4", ("esc4", 0))])
def test_node_entries_the_board_takes(spec, parsed):
    assert parse_node_spec(spec) == parsed


@pytest.mark.parametrize("spec", [0, 126, True, "esc5", "esc1@", "esc1@126", "gnss@x",
                                  "esc1@-3", "Esc1", "", None, 3.0, "esc1@١"])
def test_bad_node_entries_are_refused(spec):
    with pytest.raises(ValueError, match="is not a node ID"):
        parse_node_spec(spec)


def _scenario(**kw):
    return scenario_from_dict({"name": "n", "timeline": [{"wait": 1}],
                               "expect": [{"never": "estimator_fault"}], **kw})


def test_a_scenario_puts_dronecan_nodes_on_the_bus():
    sc = _scenario(uavcan_nodes=[125, "gnss", "esc1@11", "esc2@12"])
    assert sc.uavcan_nodes == (125, "gnss", "esc1@11", "esc2@12") and not sc.can_escs
    assert _scenario(can_escs=True, uavcan_nodes=["mag"]).can_escs
    for bad, why in ((["esc9"], "is not a node ID"), ([11, "esc1@11"], "node IDs given twice"),
                     (["esc1", "esc1@12"], "ESC given twice"), ("gnss", "a list of nodes")):
        with pytest.raises(ScenarioError, match=why):
            _scenario(uavcan_nodes=bad)
    with pytest.raises(ScenarioError, match="no ESC nodes with can_escs"):
        _scenario(can_escs=True, uavcan_nodes=["esc1@11"])


_ENTRY = st.one_of(st.integers(-5, 300), st.text(max_size=12),
                   st.from_regex(r"(gnss|mag|esc[0-9])(@[0-9]{0,4})?", fullmatch=True),
                   st.none(), st.booleans(), st.floats())


@fuzz(examples=300)
@given(st.lists(_ENTRY, max_size=6))
def test_fuzz_node_entries(entries):
    """Any scenario-file list: parsed entries the board accepts, or ValueError; never another
    exception."""
    try:
        parsed = check_node_specs(entries)
    except ValueError:
        return
    for kind, nid in parsed:
        assert kind in ("", "gnss", "mag", "esc1", "esc2", "esc3", "esc4") and 0 <= nid <= 125
