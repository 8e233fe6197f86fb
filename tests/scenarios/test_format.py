"""The scenario format: what loads, and the clear error for what does not."""

from __future__ import annotations

import pytest

from hil.cli import main
from hil.scenarios import ScenarioError, load_scenario, scenario_from_dict
from hil.scenarios.conditions import ConditionError, parse_condition
from hil.scenarios.observables import is_observable

GOOD = {
    "name": "demo", "seed": 3, "rc": "dsm", "params": {"NAV_RCL_ACT": 3},
    "events": {"lost": "rc_lost"},
    "timeline": [
        {"wait": 2},
        {"fault": {"kind": "rc.out_of_range", "target": "dsm", "duration": 1.5, "name": "oor"}},
        {"pilot": {"sticks": {"throttle": 0.5}, "ramp": 1}},
        {"gcs": {"takeoff": 4}, "at": 5},
        {"wait": {"until": "alt_agl_m > 3", "within": 20}},
    ],
    "expect": [
        {"within": 0.3, "of": "oor", "that": "rc_lost"},
        {"eventually": "not rc_lost", "after": "oor.end"},
        {"always": "motor_us between 900 2000", "from": "lost", "for": 2},
        {"never": "estimator_fault"},
    ],
}


def test_a_good_scenario_loads_with_its_events_and_texts():
    sc = scenario_from_dict(GOOD)
    assert (sc.name, sc.seed, sc.rc, sc.params) == ("demo", 3, "dsm", {"NAV_RCL_ACT": 3})
    assert [s.kind for s in sc.timeline] == ["wait", "fault", "pilot", "gcs", "wait"]
    assert sc.timeline[1].event == "oor" and sc.timeline[3].at_s == 5.0
    assert sc.fault_kinds() == {"rc.out_of_range"}
    assert [e.text for e in sc.expect] == [
        "within 0.3 s of oor: rc_lost", "eventually from oor.end: not rc_lost",
        "always from lost for 2 s: motor_us between 900 2000", "never: estimator_fault"]


@pytest.mark.parametrize("patch, message", [
    ({"timeline": [{"fault": {"kind": "rc_jammer"}}]}, "unknown fault 'rc_jammer'"),
    ({"timeline": [{"fault": {"kind": "sensor.absent", "target": "icm20602"}}]},
     "target 'icm20602' is not one of"),
    ({"timeline": [{"fault": {"kind": "gps.jump", "params": {"up_m": 3}}}]},
     "unknown parameter"),
    ({"timeline": [{"fault": {"kind": "board.crash", "duration": 2}}]}, "cannot be undone"),
    ({"timeline": [{"gcs": "arn"}]}, "unknown GCS command 'arn'"),
    ({"timeline": [{"wait": {"until": "armed"}}]}, "needs 'until' and 'within'"),
    ({"timeline": [{"clear": "nothing"}]}, "no fault named 'nothing'"),
    ({"timeline": [{"dance": 1}]}, "unknown key"),
    ({"expect": [{"sometimes": "armed"}]}, "one of within, eventually, always, never"),
    ({"expect": [{"within": 1, "of": "nowhere", "that": "armed"}]}, "unknown event 'nowhere'"),
    ({"expect": [{"never": "warp_drive"}]}, "unknown observable 'warp_drive'"),
    ({"expect": [{"never": "armed ~ 3"}]}, "unknown operator '~'"),
    ({"expect": []}, "non-empty list"),
    ({"rc": "crsf"}, "rc: one of sbus, dsm, ppm"),
    ({"seed": "one"}, "seed"),
])
def test_bad_scenarios_are_rejected_with_a_message_that_says_where(patch, message):
    data = {**GOOD, **patch}
    with pytest.raises(ScenarioError, match=message) as err:
        scenario_from_dict(data, "demo.yaml")
    assert str(err.value).startswith("demo.yaml: ")


def test_malformed_yaml_names_the_file_and_line(tmp_path):
    p = tmp_path / "bad.yaml"
    p.write_text("name: x\ntimeline:\n  - wait: [1\n")
    with pytest.raises(ScenarioError, match=r"bad.yaml: not valid YAML at line \d+"):
        load_scenario(str(p))
    with pytest.raises(ScenarioError, match="cannot read"):
        load_scenario(str(tmp_path / "missing.yaml"))


def test_cli_reports_a_bad_file_without_a_traceback(tmp_path, capsys):
    p = tmp_path / "bad.yaml"
    p.write_text("timeline: [{fault: {kind: nope}}]\nexpect: [{never: armed}]\n")
    assert main(["scenario", str(p)]) == 2
    err = capsys.readouterr().err
    assert "unknown fault 'nope'" in err and "Traceback" not in err


def test_cli_lists_the_catalogue(capsys):
    assert main(["faults"]) == 0
    out = capsys.readouterr().out
    assert "sensor.absent  [sensor]" in out and "rc.tx_off  [rc]" in out


def _eval(text, values):
    return parse_condition(text, is_observable)(values.get)


@pytest.mark.parametrize("text, values, want", [
    ("nav_state == Return", {"nav_state": "Return"}, True),
    ("nav_state == return", {"nav_state": "Return"}, True),
    ("nav_state != Return", {"nav_state": None}, False),        # missing satisfies nothing
    ("motor_us == 900 +- 2", {"motor_us": [899.0, 901.5]}, True),
    ("motor_us == 900 +- 2", {"motor_us": [899.0, 903.0]}, False),
    ("motor_us between 900 2000", {"motor_us": [950, 1999]}, True),
    ("motor_us > 1500", {"motor_us": []}, False),
    ("io.flags contains FAILSAFE", {"io.flags": ["FMU_OK", "FAILSAFE"]}, True),
    ("not io.flags contains FMU_OK", {"io.flags": ["FAILSAFE"]}, True),
    ('gcs.text contains "Baro Sensor"', {"gcs.text": ["Preflight Fail: Baro Sensor 0"]}, True),
    ("nav_state in [Hold, Return]", {"nav_state": "Hold"}, True),
    ("armed", {"armed": True}, True),
    ("not armed", {"armed": None}, False),
    ("imu_healthy[0:2]", {"imu_healthy[0:2]": [True, False]}, False),
])
def test_conditions(text, values, want):
    assert _eval(text, values) is want


def test_condition_combinations_and_errors():
    c = parse_condition({"all": ["armed", {"any": ["rc_lost", "failsafe"]}]}, is_observable)
    assert c({"armed": True, "rc_lost": False, "failsafe": True}.get)
    assert not c({"armed": True, "rc_lost": False, "failsafe": False}.get)
    for bad in ("", "armed >", "alt_agl_m > high", "motor_us between 1", True, {"both": []}):
        with pytest.raises(ConditionError):
            parse_condition(bad, is_observable)


# -- issue 18, defect 7: every malformed file is the loader's error, never a traceback ------

_BASE = "expect: [{never: armed}]\n"
_BOMB = "".join(f"l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * 9) if i else 'x'}]\n"
                for i in range(9)) + "name: *l8\n"


@pytest.mark.parametrize("text, message", [
    ("name: " + "[" * 3000 + "]" * 3000 + "\n" + _BASE, "nested deeper than"),  # RecursionError
    ("events: {e: " + "{not: " * 400 + "armed" + "}" * 400 + "}\n" + _BASE, "nested deeper"),
    ("expect:\n- always: &c {not: *c}\n", "refers to itself"),            # RecursionError
    (_BOMB + _BASE, "expands to more than"),                               # billion laughs
    ("airframe: [1]\n" + _BASE, r"airframe: an airframe number"),          # TypeError
    ("airframe: .inf\n" + _BASE, r"airframe: an airframe number"),         # OverflowError
    ("airframe: 99999999999\n" + _BASE, r"airframe.SYS_AUTOSTART: .*int32"),
    ("name: !!timestamp 1\n" + _BASE, "AttributeError"),                  # PyYAML's own
    ("name: 2001-13-45\n" + _BASE, "cannot build"),                        # PyYAML ValueError
    ("duration: .nan\n" + _BASE, r"duration: nan is outside"),
    ("duration: .inf\n" + _BASE, r"duration: inf is outside"),
    ("timeline: [{wait: 1.0e+400}]\n" + _BASE, r"timeline\[0\].wait: inf is outside"),
    ("timeline: [{wait: 1, at: " + "9" * 400 + "}]\n" + _BASE, r"timeline\[0\].at: .* outside"),
    ("timeline: [{gcs: {mission: [[.nan, 0, 5]]}}]\n" + _BASE, r"mission\[0\]\[0\]: nan"),
    ("timeline: [{fault: {kind: board.crash, name: [x]}}]\n" + _BASE, r"fault.name: an event"),
    ("timeline: [{fault: {kind: gps.jump, params: {north_m: .nan}}}]\n" + _BASE,
     r"params.north_m: nan is outside"),
    ("params: {MPC_XY_VEL_MAX: 1.0e+39}\n" + _BASE, r"params.MPC_XY_VEL_MAX: "),
    ("params: {MPC_XY_VEL_MAX: .nan}\n" + _BASE, r"params.MPC_XY_VEL_MAX: .*finite"),
    ("params: {NAV_RCL_ACT: 2.5}\n" + _BASE, r"params.NAV_RCL_ACT: .*integer"),
    ("params: {NO_SUCH_PARAM: 1}\n" + _BASE, r"unknown parameter 'NO_SUCH_PARAM'"),
    ("timeline: [{gcs: {param: {MPC_XY_VEL_MAX: 1.0e+39}}}]\n" + _BASE, r"param.MPC_XY_VEL_MAX"),
    ("initial: {lat_deg: .nan}\n" + _BASE, r"initial.lat_deg: nan is outside"),
    ("seed: " + "9" * 30 + "\n" + _BASE, "seed: an integer"),
    ("doc: [1, 2]\n" + _BASE, "doc: expected text"),
])
def test_malformed_scenario_files_are_load_errors_naming_file_and_place(tmp_path, text,
                                                                         message):
    p = tmp_path / "bad.yaml"
    p.write_text(text)
    with pytest.raises(ScenarioError, match=message) as err:
        load_scenario(str(p))
    assert str(err.value).startswith(f"{p}: ")
    assert len(str(err.value)) < 600  # a bounded message, even for a bomb


def test_a_file_that_is_not_utf8_is_a_load_error(tmp_path):
    p = tmp_path / "bin.yaml"
    p.write_bytes(b"name: \xff\xfe\n")
    with pytest.raises(ScenarioError, match="not UTF-8"):
        load_scenario(str(p))


def test_cli_reports_a_bomb_and_a_nan_duration_without_a_traceback(tmp_path, capsys):
    for i, text in enumerate((_BOMB + _BASE, "duration: .nan\n" + _BASE,
                              "name: " + "[" * 3000 + "\n")):
        p = tmp_path / f"bad{i}.yaml"
        p.write_text(text)
        assert main(["scenario", str(p)]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"hil scenario: {p}: ") and "Traceback" not in err


@pytest.mark.parametrize("run, message", [
    ("param show " + "X" * 117, "128 characters"),      # 128: one past nsh's 127
    ("param set A 1\nreboot", "one line"),               # a second command hidden in the step
    ({"run": "param save\rreboot", "may_fail": True}, "one line"),
])
def test_shell_steps_longer_than_a_console_line_are_load_errors(run, message):
    # nsh refuses a line of more than 127 characters (MAX_LINE_CHARS), and a line end makes
    # two commands of one step: both are refused when the file loads, not minutes into a run.
    data = {**GOOD, "timeline": [{"shell": run}, *GOOD["timeline"]]}
    with pytest.raises(ScenarioError, match=message) as err:
        scenario_from_dict(data, "demo.yaml")
    assert str(err.value).startswith("demo.yaml: timeline[0].shell")
    fits = {**GOOD, "timeline": [{"shell": "param show " + "X" * 116}, *GOOD["timeline"]]}
    assert len(scenario_from_dict(fits).timeline[0].arg["run"]) == 127  # nsh's limit: loads
