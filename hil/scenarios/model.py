"""A scenario as data: what to build, what to do when, what must happen by when.

Loaded from YAML (:func:`load_scenario`) or from a Python mapping (:func:`scenario_from_dict`);
every field is checked when it is loaded, so a typo is an error naming the file, the place and
the allowed values before anything boots. The format is documented in docs/faults.md.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

from firmware.platform.params import ParamError
from firmware.shell.parser import MAX_LINE_CHARS
from hil.faults import CATALOGUE, FaultError, get_kind
from hil.scenarios.document import (MAX_FILE_BYTES, ScenarioError, check_shape, parse_yaml,
                                    short_repr as _r)
from hil.scenarios.conditions import Condition, ConditionError, parse_condition
from hil.scenarios.observables import is_observable
from peripherals.dronecan.spec import check_node_specs

__all__ = ["Expectation", "Scenario", "ScenarioError", "Step", "load_scenario",
           "scenario_from_dict"]

TOP_KEYS = {"name", "doc", "seed", "rc", "airframe", "params", "initial", "one_process",
            "sample_ms", "duration", "events", "timeline", "expect", "trace", "reference",
            "known_failure", "uavcan_nodes", "can_escs", "quantum_us", "companion",
            "companion_att"}
INITIAL_KEYS = {"heading_deg", "lat_deg", "lon_deg", "alt_m", "sticks", "tx_on"}
STEP_KINDS = ("wait", "mark", "pilot", "gcs", "fault", "clear", "shell", "ready", "hover",
              "cruise", "settle")
PILOT_ACTIONS = ("sticks", "switch", "channel", "safety")
GCS_COMMANDS = ("arm", "force_arm", "disarm", "takeoff", "land", "rtl", "mode", "mission",
                "start_mission", "param")
#: mode names a GCS can select -> (PX4 main mode, sub mode)
GCS_MODES = {"manual": (1, 0), "altitude": (2, 0), "position": (3, 0), "hold": (4, 3),
             "mission": (4, 4), "return": (4, 5), "land": (4, 6), "takeoff": (4, 2),
             "stabilized": (7, 0), "acro": (5, 0)}
EXPECT_KINDS = ("within", "eventually", "always", "never")
RC_KINDS = ("sbus", "dsm", "ppm", None)
#: bounds of places and heights a scenario names (finite, and far beyond the world's use)
MAX_ALT_M = 10_000.0
MAX_DISTANCE_M = 100_000.0
#: seeds are handed to numpy's generators, which take 0..2**32-1
MAX_SEED = (1 << 32) - 1
#: longest virtual time a scenario may name (a day): a bound that keeps times finite
MAX_SECONDS = 86_400.0


@dataclass
class Step:
    kind: str                       # one of STEP_KINDS
    arg: Any                        # the step's own value, normalised per kind
    at_s: float | None = None       # run until this virtual time first
    name: str | None = None         # the event this step raises when it runs
    where: str = ""                 # "timeline[3]" for messages

    @property
    def event(self) -> str | None:
        if self.name:
            return self.name
        if self.kind == "fault":
            return self.arg["name"] or self.arg["kind"]
        if self.kind == "gcs":
            return f"gcs.{self.arg['cmd']}"
        if self.kind == "pilot":
            return f"pilot.{self.arg['action']}"
        if self.kind in ("ready", "hover", "shell"):
            return self.kind
        return None


@dataclass
class Expectation:
    kind: str                       # within | eventually | always | never
    cond: Condition
    of: str = "start"               # the event it counts from
    window_s: float | None = None   # within: deadline; always/never: window (None: to the end)
    until: str | None = None        # always/never: stop checking at this event
    label: str = ""

    @property
    def text(self) -> str:
        if self.label:
            return self.label
        if self.kind == "within":
            return f"within {self.window_s:g} s of {self.of}: {self.cond}"
        head = self.kind
        if self.of != "start":
            head += f" from {self.of}"
        if self.window_s is not None:
            head += f" for {self.window_s:g} s"
        if self.until:
            head += f" until {self.until}"
        return f"{head}: {self.cond}"


@dataclass
class Scenario:
    name: str
    doc: str = ""
    seed: int = 1
    rc: str | None = "sbus"
    airframe: int = 4011
    params: dict[str, int | float] = field(default_factory=dict)
    initial: dict[str, Any] = field(default_factory=dict)
    one_process: bool = False
    sample_ms: float = 20.0
    duration_s: float = 120.0       # hard limit of virtual time
    events: dict[str, Condition] = field(default_factory=dict)
    timeline: list[Step] = field(default_factory=list)
    expect: list[Expectation] = field(default_factory=list)
    trace: bool = True
    reference: str = ""             # where the expected behaviour comes from (PX4 docs, params)
    known_failure: str = ""         # why this tree fails it today (the library test expects
                                    # the failure, strictly: a fix turns it into a pass)
    #: DroneCAN nodes on the FMU's CAN1 as the board takes them (peripherals/dronecan/spec.py):
    #: node IDs, "gnss", "mag", "esc1".."esc4", each kind with an optional "@id"
    uavcan_nodes: tuple[int | str, ...] = ()
    can_escs: bool = False          # motors on DroneCAN ESCs (hil.system.SystemConfig)
    #: a companion computer on TELEM2; its attitude law flying the vehicle (SystemConfig)
    companion: bool = False
    companion_att: bool = False
    #: the lockstep quantum (us); the default is hil run's 500 us
    quantum_us: float = 500.0
    source: str = ""                # the file it came from

    def fault_kinds(self) -> set[str]:
        return {s.arg["kind"] for s in self.timeline if s.kind == "fault"}


def _num(v: Any, where: str, *, lo: float = 0.0, hi: float = MAX_SECONDS,
         what: str = "a number of seconds") -> float:
    """A finite number in [lo, hi]: NaN, infinities and huge integers would crash the run."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ScenarioError(f"{where}: expected {what}, got {_r(v)}")
    if not lo <= v <= hi:  # NaN fails both tests; a huge int compares without overflow
        raise ScenarioError(f"{where}: {_r(v)} is outside {lo:g}..{hi:g}")
    return float(v)


def _mapping(v: Any, where: str) -> dict:
    if not isinstance(v, dict):
        raise ScenarioError(f"{where}: expected a mapping, got {_r(v)}")
    return v


def _cond(spec: Any, where: str) -> Condition:
    try:
        return parse_condition(spec, is_observable, where)
    except ConditionError as exc:
        raise ScenarioError(str(exc)) from None


def _only(d: dict, allowed: set[str] | tuple[str, ...], where: str) -> None:
    bad = set(d) - set(allowed)
    if bad:
        raise ScenarioError(f"{where}: unknown key(s) {', '.join(sorted(map(str, bad)))} "
                            f"(allowed: {', '.join(sorted(allowed))})")


def _fault(v: Any, where: str) -> dict[str, Any]:
    if isinstance(v, str):
        v = {"kind": v}
    d = _mapping(v, where)
    _only(d, {"kind", "target", "params", "duration", "until", "name"}, where)
    if "kind" not in d:
        raise ScenarioError(f"{where}: a fault needs a 'kind' (one of: "
                            f"{', '.join(sorted(CATALOGUE))})")
    try:
        kind = get_kind(str(d["kind"]))
    except FaultError as exc:
        raise ScenarioError(f"{where}: {exc}") from None
    target = str(d.get("target") or (kind.targets[0] if kind.targets else ""))
    params = d.get("params") or {}
    _mapping(params, f"{where}.params")
    try:
        full = kind.check(target, params)
    except FaultError as exc:
        raise ScenarioError(f"{where}: {exc}") from None
    for pname, value in params.items():
        _fault_param(value, kind.params[pname], f"{where}.params.{pname}")
    name = d.get("name")
    if name is not None and (not isinstance(name, str) or not name):
        raise ScenarioError(f"{where}.name: an event name, got {_r(name)}")
    duration = d.get("duration")
    if duration is not None:
        duration = _num(duration, f"{where}.duration")
    until = _cond(d["until"], f"{where}.until") if d.get("until") is not None else None
    if (duration is not None or until is not None) and kind.stop is None:
        raise ScenarioError(f"{where}: fault {kind.name} cannot be undone, so it takes no "
                            f"duration or until")
    if duration is not None and until is not None:
        raise ScenarioError(f"{where}: give a duration or an until, not both")
    return {"kind": kind.name, "target": target, "params": full, "duration": duration,
            "until": until, "name": name}


#: largest magnitude of a fault parameter (a bias, a rate, a count): finite and far beyond use
MAX_FAULT_PARAM = 1e9


def _fault_param(value: Any, default: Any, where: str) -> None:
    """A fault parameter must have its default's type (numbers finite), as the fault's start
    function will use it that way in the middle of the run."""
    if isinstance(default, str):
        if not isinstance(value, str):
            raise ScenarioError(f"{where}: expected text, got {_r(value)}")
    elif isinstance(default, tuple):
        if not isinstance(value, (list, tuple)) or len(value) != len(default):
            raise ScenarioError(f"{where}: expected a list of {len(default)} numbers, "
                                f"got {_r(value)}")
        for i, x in enumerate(value):
            _num(x, f"{where}[{i}]", lo=-MAX_FAULT_PARAM, hi=MAX_FAULT_PARAM, what="a number")
    elif isinstance(default, bool):
        if not isinstance(value, bool):
            raise ScenarioError(f"{where}: expected true or false, got {_r(value)}")
    elif isinstance(default, int):
        if isinstance(value, bool) or not isinstance(value, int):
            raise ScenarioError(f"{where}: expected an integer, got {_r(value)}")
        _num(value, where, lo=-MAX_FAULT_PARAM, hi=MAX_FAULT_PARAM, what="an integer")
    elif isinstance(default, float):
        _num(value, where, lo=-MAX_FAULT_PARAM, hi=MAX_FAULT_PARAM, what="a number")


def _pilot(v: Any, where: str) -> dict[str, Any]:
    d = _mapping(v, where)
    _only(d, set(PILOT_ACTIONS) | {"ramp"}, where)
    acts = [k for k in d if k != "ramp"]
    if len(acts) != 1:
        raise ScenarioError(f"{where}: one pilot action per step ({', '.join(PILOT_ACTIONS)})")
    act = acts[0]
    ramp = _num(d.get("ramp", 0.0), f"{where}.ramp")
    val = d[act]
    if act == "sticks":
        _only(_mapping(val, f"{where}.sticks"), {"roll", "pitch", "yaw", "throttle"},
              f"{where}.sticks")
        for k, x in val.items():
            lo = 0.0 if k == "throttle" else -1.0
            if isinstance(x, bool) or not isinstance(x, (int, float)) or not lo <= x <= 1.0:
                raise ScenarioError(f"{where}.sticks.{k}: {_r(x)} outside {lo:g}..1")
    elif act == "switch":
        _mapping(val, f"{where}.switch")
        for k, x in val.items():
            if isinstance(x, bool) or not isinstance(x, int) or not 0 <= x <= 2:
                raise ScenarioError(f"{where}.switch.{k}: position {_r(x)} not 0, 1 or 2")
    elif act == "channel":
        _mapping(val, f"{where}.channel")
        for k, x in val.items():
            if isinstance(k, bool) or not isinstance(k, int) or isinstance(x, bool) \
                    or not isinstance(x, (int, float)) or not 800 <= x <= 2200:
                raise ScenarioError(f"{where}.channel: {_r(k)}: {_r(x)} must be channel number: "
                                    f"us in 800..2200")
    elif act == "safety":
        val = _num(val, f"{where}.safety")  # how long the button is held
    return {"action": act, "value": val, "ramp": ramp}


def _gcs(v: Any, where: str) -> dict[str, Any]:
    if isinstance(v, str):
        v = {v: None}
    d = _mapping(v, where)
    if len(d) != 1:
        raise ScenarioError(f"{where}: one GCS command per step ({', '.join(GCS_COMMANDS)})")
    (cmd, arg), = d.items()
    if cmd not in GCS_COMMANDS:
        raise ScenarioError(f"{where}: unknown GCS command {_r(cmd)} (known: "
                            f"{', '.join(GCS_COMMANDS)})")
    if cmd == "takeoff":
        arg = _num(arg if arg is not None else 5.0, f"{where}.takeoff", hi=MAX_ALT_M,
                   what="an altitude in m")
    elif cmd == "mode":
        if not isinstance(arg, str) or arg.lower() not in GCS_MODES:
            raise ScenarioError(f"{where}.mode: {_r(arg)} is not one of "
                                f"{', '.join(GCS_MODES)}")
        arg = arg.lower()
    elif cmd == "mission":
        if not isinstance(arg, list) or not arg:
            raise ScenarioError(f"{where}.mission: a list of [north_m, east_m, alt_m] "
                                f"waypoints relative to home")
        for i, wp in enumerate(arg):
            if not isinstance(wp, list) or len(wp) != 3:
                raise ScenarioError(f"{where}.mission[{i}]: [north_m, east_m, alt_m], got {_r(wp)}")
            for j, x in enumerate(wp):
                _num(x, f"{where}.mission[{i}][{j}]", lo=-MAX_DISTANCE_M, hi=MAX_DISTANCE_M,
                     what="metres")
    elif cmd == "param":
        arg = _params(arg, f"{where}.param")
    elif arg is not None:
        raise ScenarioError(f"{where}.{cmd} takes no value")
    return {"cmd": cmd, "arg": arg}


def _shell_line(v: Any, where: str) -> str:
    """A shell step's command: one console line as nsh takes it, at most MAX_LINE_CHARS
    characters (nsh refuses a longer one) and without a line end (which would make it two
    commands, the second run unseen by the step's status)."""
    if not isinstance(v, str) or not v.strip():
        raise ScenarioError(f"{where}: an nsh command line, got {_r(v)}")
    if "\n" in v or "\r" in v:
        raise ScenarioError(f"{where}: one line, without a line end (got {_r(v)}); "
                            f"write one shell step per command")
    if len(v) > MAX_LINE_CHARS:
        raise ScenarioError(f"{where}: a command line of {len(v)} characters; nsh takes at "
                            f"most {MAX_LINE_CHARS}")
    return v


def _wait(v: Any, where: str) -> dict[str, Any]:
    if not isinstance(v, dict):
        return {"for": _num(v, where)}
    _only(v, {"until", "within"}, where)
    if "until" not in v or "within" not in v:
        raise ScenarioError(f"{where}: a conditional wait needs 'until' and 'within' "
                            f"(a virtual-time budget)")
    return {"until": _cond(v["until"], f"{where}.until"), "within": _num(v["within"],
                                                                         f"{where}.within")}


def _step(i: int, raw: Any) -> Step:
    where = f"timeline[{i}]"
    d = _mapping(raw, where)
    kinds = [k for k in d if k in STEP_KINDS]
    _only(d, set(STEP_KINDS) | {"at", "name"}, where)
    if len(kinds) != 1:
        raise ScenarioError(f"{where}: one action per step, one of {', '.join(STEP_KINDS)} "
                            f"(got {', '.join(kinds) or 'none'})")
    kind = kinds[0]
    val = d[kind]
    w = f"{where}.{kind}"
    if kind == "wait":
        arg: Any = _wait(val, w)
    elif kind == "mark":
        if not isinstance(val, str) or not val:
            raise ScenarioError(f"{w}: an event name")
        arg = val
    elif kind == "pilot":
        arg = _pilot(val, w)
    elif kind == "gcs":
        arg = _gcs(val, w)
    elif kind == "fault":
        arg = _fault(val, w)
    elif kind == "clear":
        if not isinstance(val, str):
            raise ScenarioError(f"{w}: the name of a fault started earlier")
        arg = val
    elif kind == "shell":
        # "cmd" or {run: "cmd", may_fail: true} (a command whose failure is the point, e.g. a
        # parameter save to a broken FRAM: its status is the observable shell.status)
        may_fail = False
        if isinstance(val, dict):
            _only(val, {"run", "may_fail"}, w)
            may_fail = val.get("may_fail", False)
            if not isinstance(may_fail, bool):
                raise ScenarioError(f"{w}.may_fail: true or false")
            val = val.get("run")
        arg = {"run": _shell_line(val, w), "may_fail": may_fail}
    elif kind == "ready":
        arg = {"within": _num((val or {}).get("within", 60) if isinstance(val, dict) else
                              (val if val is not None else 60), w)}
    elif kind == "hover":
        val = val if isinstance(val, dict) else {"alt": val if val is not None else 5.0}
        _only(val, {"alt", "within"}, w)
        arg = {"alt": _num(val.get("alt", 5.0), f"{w}.alt", hi=MAX_ALT_M, what="an altitude in m"),
               "within": _num(val.get("within", 90), f"{w}.within")}
    elif kind == "cruise":
        # the airframe's default mission (hil.missions), flown until waypoint N is passed
        val = val if isinstance(val, dict) else {"waypoint": val if val is not None else 1}
        _only(val, {"waypoint", "within"}, w)
        wp = val.get("waypoint", 1)
        if isinstance(wp, bool) or not isinstance(wp, int) or not 1 <= wp <= 4:
            raise ScenarioError(f"{w}.waypoint: a waypoint of the default square, 1..4, "
                                f"got {_r(wp)}")
        arg = {"waypoint": wp, "within": _num(val.get("within", 240), f"{w}.within")}
    else:  # settle
        arg = {"within": _num(val, w)}
    at = d.get("at")
    name = d.get("name")
    if name is not None and (not isinstance(name, str) or not name):
        raise ScenarioError(f"{where}.name: an event name, got {_r(name)}")
    if kind == "mark":
        name = arg
    return Step(kind, arg, _num(at, f"{where}.at") if at is not None else None, name, where)


def _expectation(i: int, raw: Any) -> Expectation:
    where = f"expect[{i}]"
    d = _mapping(raw, where)
    kinds = [k for k in d if k in EXPECT_KINDS]
    if len(kinds) != 1:
        raise ScenarioError(f"{where}: one of {', '.join(EXPECT_KINDS)} per expectation "
                            f"(got {', '.join(map(str, d)) or 'nothing'})")
    kind = kinds[0]
    label = str(d.get("name", ""))
    if kind == "within":
        _only(d, {"within", "of", "that", "name"}, where)
        if "that" not in d:
            raise ScenarioError(f"{where}: 'within' needs 'that: CONDITION'")
        return Expectation("within", _cond(d["that"], f"{where}.that"), str(d.get("of", "start")),
                           _num(d["within"], f"{where}.within"), None, label)
    _only(d, {kind, "from", "after", "for", "until", "name"}, where)
    window = _num(d["for"], f"{where}.for") if "for" in d else None
    of = str(d.get("from", d.get("after", "start")))
    until = str(d["until"]) if "until" in d else None
    return Expectation(kind, _cond(d[kind], f"{where}.{kind}"), of, window, until, label)


def scenario_from_dict(data: Any, source: str = "<dict>") -> Scenario:
    """A checked :class:`Scenario` from a mapping (the YAML document's shape)."""
    try:
        return _from_dict(data, source)
    except ScenarioError as exc:
        raise ScenarioError(f"{source}: {exc}") from None


def _params(v: Any, where: str) -> dict[str, int | float]:
    """``NAME: value`` pairs converted as the FMU will store them (the parameter layer's own
    conversion, float32 or int32), so a value the board would refuse at boot (an unknown name,
    1e39, NaN, a fraction for an integer) is a load error instead."""
    from hil.params_doc import param_def  # imports every module: only when a file has params

    out: dict[str, int | float] = {}
    for k, x in _mapping(v, where).items():
        d = param_def(k)
        if d is None:
            raise ScenarioError(f"{where}: unknown parameter {_r(k)}")
        try:
            d.coerce(x)
        except ParamError as exc:
            raise ScenarioError(f"{where}.{k}: {exc}") from None
        out[k] = x
    return out


def _text(d: dict, key: str, default: str = "") -> str:
    v = d.get(key)
    if v is None:
        return default
    if not isinstance(v, (str, int, float)) or isinstance(v, bool):
        raise ScenarioError(f"{key}: expected text, got {_r(v)}")
    return str(v).strip()


def _flag(d: dict, key: str, default: bool) -> bool:
    v = d.get(key, default)
    if not isinstance(v, bool):
        raise ScenarioError(f"{key}: true or false, got {_r(v)}")
    return v


def _initial(v: Any) -> dict[str, Any]:
    initial = _mapping(v, "initial")
    _only(initial, INITIAL_KEYS, "initial")
    bounds = {"heading_deg": (-360.0, 360.0), "lat_deg": (-90.0, 90.0),
              "lon_deg": (-180.0, 180.0), "alt_m": (-500.0, MAX_ALT_M)}
    for k, (lo, hi) in bounds.items():
        if k in initial:
            _num(initial[k], f"initial.{k}", lo=lo, hi=hi, what="a number")
    if "sticks" in initial:
        sticks = _mapping(initial["sticks"], "initial.sticks")
        _only(sticks, {"roll", "pitch", "yaw", "throttle"}, "initial.sticks")
        for k, x in sticks.items():
            _num(x, f"initial.sticks.{k}", lo=0.0 if k == "throttle" else -1.0, hi=1.0,
                 what="a stick position")
    if "tx_on" in initial and not isinstance(initial["tx_on"], bool):
        raise ScenarioError(f"initial.tx_on: true or false, got {_r(initial['tx_on'])}")
    return dict(initial)


def _from_dict(data: Any, source: str) -> Scenario:
    check_shape(data)
    d = _mapping(data, "scenario")
    _only(d, TOP_KEYS, "scenario")
    name = _text(d, "name") or os.path.splitext(os.path.basename(source))[0]
    seed = d.get("seed", 1)
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed <= MAX_SEED:
        raise ScenarioError(f"seed: an integer 0..{MAX_SEED}, got {_r(seed)}")
    rc = d.get("rc", "sbus")
    if not (rc is None or isinstance(rc, str)) or rc not in RC_KINDS:
        raise ScenarioError(f"rc: one of sbus, dsm, ppm or null, got {_r(rc)}")
    airframe = d.get("airframe", 4011)
    if isinstance(airframe, str):  # a name, as hil run --airframe takes it
        from hil.airframes import resolve

        try:
            airframe = resolve(airframe).id
        except ValueError as exc:
            raise ScenarioError(f"airframe: {exc}") from None
    if isinstance(airframe, bool) or not isinstance(airframe, int):
        raise ScenarioError(f"airframe: an airframe number (SYS_AUTOSTART) or name, got "
                            f"{_r(airframe)}")
    _params({"SYS_AUTOSTART": airframe}, "airframe")
    params = _params(d.get("params") or {}, "params")
    initial = _initial(d.get("initial") or {})
    nodes = d.get("uavcan_nodes") or []
    can_escs = _flag(d, "can_escs", False)
    if not isinstance(nodes, list):
        raise ScenarioError(f"uavcan_nodes: a list of nodes (IDs 1..125, 'gnss', 'mag', "
                            f"'esc1'..'esc4', kinds with an optional '@id'), got {_r(nodes)}")
    try:
        parsed = check_node_specs(nodes)
    except ValueError as exc:
        raise ScenarioError(f"uavcan_nodes: {str(exc)[:200]}") from None
    if can_escs and any(kind.startswith("esc") for kind, _ in parsed):
        raise ScenarioError("uavcan_nodes: no ESC nodes with can_escs (it plugs in esc1..esc4)")
    events = {}
    for ev, spec in _mapping(d.get("events") or {}, "events").items():
        events[str(ev)] = _cond(spec, f"events.{ev}")
    timeline_raw = d.get("timeline") or []
    if not isinstance(timeline_raw, list):
        raise ScenarioError("timeline: a list of steps")
    timeline = [_step(i, s) for i, s in enumerate(timeline_raw)]
    expect_raw = d.get("expect") or []
    if not isinstance(expect_raw, list) or not expect_raw:
        raise ScenarioError("expect: a non-empty list of expectations (a scenario without "
                            "one asserts nothing)")
    started: set[str] = set()
    for s in timeline:
        if s.kind == "fault":
            started.add(s.event or "")
        if s.kind == "clear" and s.arg not in started:
            raise ScenarioError(f"{s.where}.clear: no fault named {_r(s.arg)} started before it")
    expect = [_expectation(i, e) for i, e in enumerate(expect_raw)]
    known = {"start"} | set(events)
    for s in timeline:
        if s.event:
            known |= {s.event, f"{s.event}.end"}
    for i, e in enumerate(expect):
        for ev in (e.of, e.until):
            if ev is not None and ev not in known:
                raise ScenarioError(f"expect[{i}]: unknown event {_r(ev)} (known: "
                                    f"{', '.join(sorted(known))})")
    return Scenario(
        name=name, doc=_text(d, "doc"), seed=seed, rc=rc,
        airframe=airframe, params=params, initial=initial,
        one_process=_flag(d, "one_process", False),
        sample_ms=_num(d.get("sample_ms", 20.0), "sample_ms", lo=1.0, hi=1000.0,
                       what="milliseconds"),
        duration_s=_num(d.get("duration", 120.0), "duration", lo=0.001), events=events,
        timeline=timeline, expect=expect, trace=_flag(d, "trace", True),
        reference=_text(d, "reference"), known_failure=_text(d, "known_failure"),
        source=source, uavcan_nodes=tuple(nodes), can_escs=can_escs,
        quantum_us=_quantum_us(d.get("quantum_us", 500)),
        companion=_flag(d, "companion", False), companion_att=_flag(d, "companion_att", False))


#: lockstep quanta a scenario may choose (us): hil run's 500 and its neighbours
QUANTA_US = (250, 500, 1000, 2000)


def _quantum_us(v: Any) -> float:
    if isinstance(v, bool) or v not in QUANTA_US:
        raise ScenarioError(f"quantum_us: one of {', '.join(map(str, QUANTA_US))} "
                            f"(microseconds), got {_r(v)}")
    return float(v)


def load_scenario(path: str) -> Scenario:
    """Load and check a YAML scenario file."""
    try:
        with open(path, "rb") as f:
            raw = f.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise ScenarioError(f"{path}: cannot read: {exc.strerror}") from None
    if len(raw) > MAX_FILE_BYTES:
        raise ScenarioError(f"{path}: larger than {MAX_FILE_BYTES} bytes")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ScenarioError(f"{path}: not UTF-8 text (byte {exc.start})") from None
    return scenario_from_dict(parse_yaml(text, path), path)
