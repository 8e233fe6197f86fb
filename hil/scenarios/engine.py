"""Running a scenario: build the rig, play the timeline, judge the expectations in virtual time.

The engine hooks a :class:`Monitor` into the orchestrator's ``on_quantum``: every
``sample_ms`` of virtual time (and whoever advances the clock: the timeline, a GCS helper
waiting for its acknowledgement) it reads the observables the scenario needs, records named
events the first time their condition holds, ends faults whose ``until`` holds, and moves every
expectation along (pending, met at t, broken at t). Fault starts and ends happen on quantum
boundaries through :class:`hil.faults.Injector`. Met times are sample times, at most one
sample after the condition became true.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from hil.faults import ActiveFault, Injector
from hil.gcs import GcsTimeout
from hil.scenarios.model import GCS_MODES, Expectation, Scenario, ScenarioError, Step
from hil.scenarios.observables import Sampler

__all__ = ["ExpectationResult", "Monitor", "ScenarioResult", "run_scenario"]

NS = 1_000_000_000
M_PER_DEG_LAT = 111_132.954
#: parameters every scenario starts from (a scenario's own params override them): the magnetic
#: declination of the world's home, as the default flight sets it.
BASE_PARAMS: dict[str, int | float] = {"EKF2_MAG_DECL": 2.6}


@dataclass
class ExpectationResult:
    text: str
    kind: str
    verdict: str = "pending"        # pass | fail (pending only while running)
    t_met_s: float | None = None
    t_broken_s: float | None = None
    t_event_s: float | None = None  # when the event it counts from happened
    reason: str = ""

    @property
    def latency_s(self) -> float | None:
        """Time from the event to the condition (``within``/``eventually``)."""
        if self.t_met_s is None or self.t_event_s is None:
            return None
        return round(self.t_met_s - self.t_event_s, 4)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self) | {"latency_s": self.latency_s}


@dataclass
class ScenarioResult:
    name: str
    seed: int
    passed: bool
    expectations: list[ExpectationResult]
    events: dict[str, float]
    aborted: str | None = None
    t_end_s: float = 0.0
    wall_s: float = 0.0
    rtf: float = 0.0
    out_dir: str = ""
    log: str | None = None
    trace: str | None = None
    source: str = ""
    faults: list[dict[str, Any]] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["expectations"] = [e.as_dict() for e in self.expectations]
        return d


class _State:
    """One expectation while the scenario runs."""

    def __init__(self, exp: Expectation) -> None:
        self.exp = exp
        self.res = ExpectationResult(exp.text, exp.kind)
        self.done = False

    def decide(self, verdict: str, t_s: float, reason: str = "") -> None:
        self.done = True
        self.res.verdict = verdict
        if verdict == "pass":
            self.res.t_met_s = round(t_s, 4)
        else:
            self.res.t_broken_s = round(t_s, 4)
        self.res.reason = reason

    def step(self, t_s: float, events: dict[str, float], read: Callable[[str], Any]) -> None:
        if self.done:
            return
        e = self.exp
        te = events.get(e.of)
        if te is None or t_s < te:
            return
        self.res.t_event_s = te
        if e.kind == "within":
            if e.cond(read):
                self.decide("pass", t_s)
            elif t_s > te + e.window_s + 1e-9:
                self.decide("fail", te + e.window_s, f"not true within {e.window_s:g} s of "
                                                     f"{e.of} (at {te:.3f} s)")
            return
        if e.kind == "eventually":
            if e.cond(read):
                self.decide("pass", t_s)
            return
        # always / never: inside the window?
        end = te + e.window_s if e.window_s is not None else math.inf
        if e.until is not None and e.until in events:
            end = min(end, events[e.until])
        if t_s > end + 1e-9:
            self.decide("pass", end)
            return
        holds = e.cond(read)
        if e.kind == "always" and not holds:
            self.decide("fail", t_s, "became false")
        elif e.kind == "never" and holds:
            self.decide("fail", t_s, "became true")

    def finish(self, t_s: float, events: dict[str, float]) -> None:
        if self.done:
            return
        e = self.exp
        if e.of not in events:
            self.decide("fail", t_s, f"event {e.of!r} never happened")
        elif e.kind == "within":
            self.decide("fail", t_s, f"scenario ended before the {e.window_s:g} s deadline "
                                     f"without the condition")
        elif e.kind == "eventually":
            self.decide("fail", t_s, "never became true")
        else:
            self.decide("pass", t_s)
            self.res.t_met_s = None

    @property
    def settled(self) -> bool:
        """Decided, or an open-ended always/never (judged at the end)."""
        return self.done or (self.exp.kind in ("always", "never") and self.exp.window_s is None)


class Monitor:
    """Samples observables on quantum boundaries and judges events and expectations."""

    def __init__(self, sc: Scenario, orch: Any, sampler: Sampler, injector: Injector) -> None:
        self.sc = sc
        self.orch = orch
        self.sampler = sampler
        self.injector = injector
        self.period_ns = max(int(sc.sample_ms * 1_000_000), orch.quantum_ns)
        self.next_ns = 0
        self.events: dict[str, float] = {"start": 0.0}
        self.states = [_State(e) for e in sc.expect]
        self.until_faults: list[tuple[ActiveFault, Any]] = []
        self.samples = 0
        self.error: str | None = None

    def __call__(self, orch: Any) -> None:
        if orch.t_ns >= self.next_ns:
            self.sample()

    def event(self, name: str) -> None:
        """Record an event now (the first occurrence counts) and judge at once."""
        if name not in self.events:
            self.events[name] = round(self.orch.t_ns / NS, 6)
            self.sample()

    def sample(self) -> None:
        t_ns = self.orch.t_ns
        self.next_ns = t_ns - t_ns % self.period_ns + self.period_ns
        self.samples += 1
        s = self.sampler
        s.new_sample()
        t_s = round(t_ns / NS, 6)
        read = s.read
        try:
            for name, cond in self.sc.events.items():
                if name not in self.events and cond(read):
                    self.events[name] = t_s
            for af, cond in list(self.until_faults):
                if cond(read):
                    self.injector.stop(af)
                    self.until_faults.remove((af, cond))
            for st in self.states:
                st.step(t_s, self.events, read)
        except Exception as exc:  # noqa: BLE001 - an observable failing is reported, not fatal
            if self.error is None:
                self.error = f"t={t_s:.3f} s: reading observables failed: {exc!r}"

    def check(self, cond: Any) -> bool:
        return bool(cond(self.sampler.read))

    def settled(self) -> bool:
        return all(st.settled for st in self.states)

    def finish(self) -> list[ExpectationResult]:
        t_s = round(self.orch.t_ns / NS, 6)
        for st in self.states:
            st.finish(t_s, self.events)
        return [st.res for st in self.states]


class _Aborted(Exception):
    pass


class Runner:
    """Plays a scenario's timeline on a built rig."""

    def __init__(self, sc: Scenario, orch: Any, dev: dict[str, Any], out_dir: str,
                 progress: Callable[[str], None] | None = None) -> None:
        self.sc = sc
        self.orch = orch
        self.dev = dev
        self.out_dir = out_dir
        self.say = progress or (lambda msg: None)
        self.gcs_results: dict[str, Any] = {}
        self.sampler = Sampler(orch, dev, self.gcs_results)
        self.injector = Injector(orch, dev)
        self.injector.log = self.say
        self.monitor = Monitor(sc, orch, self.sampler, self.injector)
        self.faults: dict[str, ActiveFault] = {}
        self.limit_ns = int(sc.duration_s * NS)
        self._ready = False

    # -- time ---------------------------------------------------------------------------------

    def advance(self, seconds: float) -> None:
        end = self.orch.t_ns + int(round(seconds * NS))
        if end > self.limit_ns:
            self.orch.run(until_ns=max(self.orch.t_ns, self.limit_ns))
            raise _Aborted(f"scenario duration {self.sc.duration_s:g} s reached")
        self.orch.run(until_ns=end)

    def wait_until(self, cond: Any, within_s: float, what: str) -> None:
        end = self.orch.t_ns + int(within_s * NS)
        step_ns = self.monitor.period_ns
        while True:
            self.sampler.new_sample()
            if self.monitor.check(cond):
                return
            if self.orch.t_ns >= end:
                raise _Aborted(f"{what}: not true within {within_s:g} s (virtual)")
            self.advance(min(step_ns, end - self.orch.t_ns) / NS)

    # -- the timeline -------------------------------------------------------------------------

    def log_from_boot(self) -> None:
        """Have the FMU log from boot, so a ground scenario has a ULog too: the operator sets
        SDLOG_MODE 1 on the console and restarts the logger once the shell is up (the
        multicopter defaults reset SDLOG_MODE to 0 on a fresh airframe, so a parameter given
        at build time would not survive)."""
        for _ in range(50):
            status, out = self.orch.call("fmu", "shell", "logger status")
            if status == 0 and "running" in out:
                break
            self.advance(0.1)
        else:
            raise _Aborted("the FMU's logger did not start within 5 s")
        for line in ("param set SDLOG_MODE 1", "logger stop", "logger start"):
            status, out = self.orch.call("fmu", "shell", line)
            if status != 0:
                raise _Aborted(f"nsh {line!r} failed: {out.strip()}")

    def play(self) -> None:
        self.log_from_boot()
        for step in self.sc.timeline:
            if step.at_s is not None and self.orch.t_ns < step.at_s * NS:
                self.advance(step.at_s - self.orch.t_ns / NS)
            try:
                getattr(self, f"_do_{step.kind}")(step)
            except _Aborted as exc:
                raise _Aborted(f"{step.where} ({step.kind}): {exc}") from None
            except ScenarioError as exc:
                raise _Aborted(f"{step.where} ({step.kind}): {exc}") from None
            if step.event:
                self.monitor.event(step.event)

    def _cond(self, text: str) -> Any:
        from hil.scenarios.model import _cond

        return _cond(text, "engine")

    def _do_wait(self, step: Step) -> None:
        if "for" in step.arg:
            self.advance(step.arg["for"])
        else:
            self.wait_until(step.arg["until"], step.arg["within"], f"wait for {step.arg['until']}")

    def _do_mark(self, step: Step) -> None:
        pass

    def _do_settle(self, step: Step) -> None:
        end = self.orch.t_ns + int(step.arg["within"] * NS)
        while not self.monitor.settled() and self.orch.t_ns < end:
            self.advance(min(self.monitor.period_ns, end - self.orch.t_ns) / NS)

    def _do_pilot(self, step: Step) -> None:
        a, t = step.arg, self.orch.t_ns
        if a["action"] == "safety":
            self.dev["safety"].press(t, hold_s=a["value"])
            return
        rc = self.dev.get("rc")
        if rc is None:
            raise ScenarioError("the pilot needs an RC transmitter (rc: sbus, dsm or ppm)")
        tx, ramp = rc.tx, int(a["ramp"] * NS)
        if a["action"] == "sticks":
            tx.set_sticks(t, ramp_ns=ramp, **a["value"])
        elif a["action"] == "switch":
            for name, pos in a["value"].items():
                try:
                    tx.set_switch(t, name, pos)
                except KeyError as exc:
                    raise ScenarioError(str(exc.args[0])) from None
        else:
            for ch, us in a["value"].items():
                try:
                    tx.set(t, int(ch), us, ramp_ns=ramp)
                except ValueError as exc:
                    raise ScenarioError(str(exc)) from None

    def _gcs(self) -> Any:
        gcs = self.dev.get("gcs")
        if gcs is None:
            raise ScenarioError("no GCS on this rig")
        return gcs

    def _do_gcs(self, step: Step) -> None:
        gcs, cmd, arg = self._gcs(), step.arg["cmd"], step.arg["arg"]
        try:
            if cmd == "param":
                for name, value in arg.items():
                    gcs.param_set(name, value)
                self.gcs_results[cmd] = 0
                return
            if cmd == "mission":
                home = gcs.last.get("HOME_POSITION")
                if home is None:
                    raise ScenarioError("mission upload needs a home position (wait for "
                                        "home_set first)")
                lat0, lon0 = home.latitude * 1e-7, home.longitude * 1e-7
                m_lon = M_PER_DEG_LAT * math.cos(math.radians(lat0))
                items = [(lat0 + n / M_PER_DEG_LAT, lon0 + e / m_lon, alt) for n, e, alt in arg]
                self.gcs_results[cmd] = gcs.upload_mission(items)
                return
            if cmd == "mode":
                ack = gcs.set_mode(*GCS_MODES[arg])
            elif cmd == "takeoff":
                ack = gcs.takeoff(arg)
            elif cmd == "force_arm":
                ack = gcs.arm(force=True)
            else:
                ack = getattr(gcs, cmd)()
            self.gcs_results[cmd] = ack.result
        except GcsTimeout:
            self.gcs_results[cmd] = "timeout"
        self.say(f"t={self.orch.t_ns / NS:.3f} s: gcs {cmd} -> {self.gcs_results[cmd]}")

    def _do_fault(self, step: Step) -> None:
        a = step.arg
        from hil.faults import FaultError

        try:
            af = self.injector.start(a["kind"], a["target"], a["params"],
                                     duration_s=a["duration"])
        except FaultError as exc:
            raise ScenarioError(str(exc)) from None
        name = step.event or a["kind"]
        self.faults[name] = af
        if a["until"] is not None:
            self.monitor.until_faults.append((af, a["until"]))
        if af.kind.stop is not None:
            def on_end(now: int, name: str = name) -> None:
                self.monitor.events.setdefault(f"{name}.end", round(now / NS, 6))
            self._watch_end(af, on_end)

    def _watch_end(self, af: ActiveFault, fn: Callable[[int], None]) -> None:
        def poll(orch: Any) -> None:
            if af.t_stop_ns is not None:
                fn(af.t_stop_ns)
                orch.on_quantum.remove(poll)
        self.orch.on_quantum.append(poll)

    def _do_clear(self, step: Step) -> None:
        self.injector.stop(self.faults[step.arg])

    def _do_shell(self, step: Step) -> None:
        line = step.arg["run"]
        status, out = self.orch.call("fmu", "shell", line)
        self.sampler.shell = {"status": status, "output": out}
        self.say(f"t={self.orch.t_ns / NS:.3f} s: nsh> {line}: {out.strip()}")
        if status != 0 and not step.arg["may_fail"]:
            raise ScenarioError(f"nsh command {line!r} failed ({status}): {out.strip()}")

    def _do_ready(self, step: Step) -> None:
        """Wait for a 3D fix and a home position, then press the safety switch, as a pilot
        does once the vehicle is ready (the IO takes the button only then)."""
        self.wait_until(self._cond("home_set"), step.arg["within"], "home position")
        self.wait_until(self._cond("gps_fix >= 3"), 10.0, "GPS 3D fix")
        self.dev["safety"].press(self.orch.t_ns + NS // 10, hold_s=1.5)
        self.wait_until(self._cond("io.flags contains SAFETY_OFF"), 10.0, "safety switch off")
        self.advance(0.5)
        self._ready = True

    def _do_hover(self, step: Step) -> None:
        """Ready, arm, take off to ``alt`` and wait until it is reached."""
        a = step.arg
        t_end = self.orch.t_ns + int(a["within"] * NS)
        if not self._ready:
            self._do_ready(Step("ready", {"within": a["within"]}))
        gcs = self._gcs()
        try:
            ack = gcs.arm(timeout_s=5)
        except GcsTimeout:
            raise ScenarioError("arming: no acknowledgement") from None
        if ack.result != 0:
            text = gcs.last.get("STATUSTEXT")
            raise ScenarioError(f"arming refused ({ack.result}): {text.text if text else ''}")
        ack = gcs.takeoff(a["alt"])
        if ack.result != 0:
            raise ScenarioError(f"takeoff refused ({ack.result})")
        left = max(1.0, (t_end - self.orch.t_ns) / NS)
        self.wait_until(self._cond(f"alt_agl_m > {a['alt'] - 0.5}"), left,
                        f"reaching {a['alt']:g} m")
        self.advance(1.0)


    def _do_cruise(self, step: Step) -> None:
        """Ready, upload the airframe's default mission (hil.missions), arm, start it, and
        wait until the vehicle has passed waypoint ``waypoint`` of its square (a plane is then
        in cruise at the mission's altitude and airspeed)."""
        from hil.airframes import resolve
        from hil.missions import mission_for

        a = step.arg
        t_end = self.orch.t_ns + int(a["within"] * NS)
        if not self._ready:
            self._do_ready(Step("ready", {"within": a["within"]}))
        gcs = self._gcs()
        home = gcs.last.get("HOME_POSITION")
        mission = mission_for(resolve(self.sc.airframe).vehicle_class)
        items = mission.items(home.latitude * 1e-7, home.longitude * 1e-7,
                              gcs.target_system, gcs.target_component)
        if gcs.upload_mission(items) != 0:
            raise ScenarioError("the default mission was refused")
        ack = gcs.arm(timeout_s=5)
        if ack.result != 0:
            text = gcs.last.get("STATUSTEXT")
            raise ScenarioError(f"arming refused ({ack.result}): {text.text if text else ''}")
        gcs.start_mission()
        mark = gcs.mark()
        seq = a["waypoint"] + mission.first_waypoint_seq - 1   # a VTOL's come after its DO items

        def passed() -> bool:
            return any(m.seq >= seq for m in gcs.messages("MISSION_ITEM_REACHED", since=mark))
        while not passed():
            if self.orch.t_ns >= t_end:
                raise ScenarioError(f"waypoint {seq} not reached within {a['within']:g} s")
            self.advance(0.2)
        self.say(f"t={self.orch.t_ns / NS:.3f} s: cruise: waypoint {seq} passed")


def _apply_initial(sc: Scenario, dev: dict[str, Any], seed: int) -> None:
    ini = sc.initial
    world_keys = {k: ini[k] for k in ("heading_deg", "lat_deg", "lon_deg", "alt_m") if k in ini}
    if world_keys:
        from hil.world import World

        dev["world"].world = World(seed=seed, **world_keys)
    rc = dev.get("rc")
    if rc is not None:
        if "sticks" in ini:
            try:
                rc.tx.set_sticks(0, **ini["sticks"])
            except (TypeError, ValueError) as exc:
                raise ScenarioError(f"initial.sticks: {exc}") from None
        if ini.get("tx_on") is False:
            rc.tx.power(0, False)


def _newest_log(out_dir: str) -> str | None:
    root = Path(out_dir) / "sd" / "log"
    logs = sorted(root.rglob("*.ulg"), key=lambda p: (p.stat().st_mtime, str(p))) \
        if root.exists() else []
    return str(logs[-1]) if logs else None


def run_scenario(sc: Scenario, *, seed: int | None = None, out_dir: str = "out/scenario",
                 one_process: bool | None = None, params: dict[str, Any] | None = None,
                 progress: Callable[[str], None] | None = None) -> ScenarioResult:
    """Run a scenario and judge it. ``seed``, ``one_process`` and ``params`` override the
    scenario's own (a campaign's variations)."""
    from hil.system import SystemConfig, build_system

    seed = sc.seed if seed is None else seed
    local = sc.one_process if one_process is None else one_process
    os.makedirs(out_dir, exist_ok=True)
    trace = os.path.join(out_dir, "trace.bin") if sc.trace else None
    all_params = {**BASE_PARAMS, **sc.params, **(params or {})}
    cfg = SystemConfig(seed=seed, out_dir=out_dir, airframe=sc.airframe,
                       mode="local" if local else "process", params=all_params, rc=sc.rc,
                       gcs=True, trace_path=trace, uavcan_nodes=sc.uavcan_nodes,
                       can_escs=sc.can_escs, quantum_ns=int(sc.quantum_us * 1000),
                       companion=sc.companion, companion_att=sc.companion_att)
    orch, dev = build_system(cfg)
    _apply_initial(sc, dev, seed)
    runner = Runner(sc, orch, dev, out_dir, progress)
    orch.on_quantum.append(runner.monitor)
    runner.injector.install()
    orch.log = runner.say
    aborted = None
    wall0 = time.perf_counter()
    with orch:
        dev["gcs"].attach(orch)
        runner.monitor.sample()
        try:
            runner.play()
        except _Aborted as exc:
            aborted = str(exc)
            runner.say(f"aborted: {aborted}")
        expectations = runner.monitor.finish()
        rtf = orch.rtf
    wall = time.perf_counter() - wall0
    if runner.monitor.error and not aborted:
        aborted = runner.monitor.error
    passed = aborted is None and all(e.verdict == "pass" for e in expectations)
    faults = [{"kind": af.kind.name, "target": af.target, "params": af.params,
               "t_start_s": af.t_start_ns / NS,
               "t_stop_s": None if af.t_stop_ns is None else af.t_stop_ns / NS}
              for af in runner.injector.history]
    return ScenarioResult(sc.name, seed, passed, expectations, dict(runner.monitor.events),
                          aborted, round(orch.t_ns / NS, 3), round(wall, 2), round(rtf, 3),
                          out_dir, _newest_log(out_dir), trace, sc.source, faults)
