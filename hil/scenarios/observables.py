"""What a scenario can look at, read only through the rig's public hooks.

Every observable is read at a sample instant (the engine samples every ``sample_ms`` of
virtual time) and cached for that instant, so a topic read by three expectations crosses the
board boundary once. Sources:

* the FMU's uORB topics (``orch.call("fmu", "topic", name)``), named conveniences below and
  the generic ``topic.<name>[.<instance>].<field>[index]`` (a nested message's field:
  ``topic.esc_status.esc[1].esc_errorcount``);
* the IO board's status and pins (``orch.call("io", "status" | "pwm")``);
* the world: motor pulses at the ESC inputs and the vehicle's true state;
* the orchestrator: which boards are alive, how often a board rebooted;
* the virtual-time GCS: STATUSTEXTs it received and the results of the scenario's commands.

A value that cannot be read (a topic never published, a dead or hung board) is ``None``, which
satisfies no condition.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from board.endpoint import BoardDied

__all__ = ["OBSERVABLES", "Sampler", "is_observable"]

#: vehicle_status.nav_state -> PX4's mode name (firmware/modules/commander/modes.py)
NAV_NAMES = {0: "Manual", 1: "Altitude", 2: "Position", 3: "Mission", 4: "Hold", 5: "Return",
             10: "Acro", 12: "Descend", 13: "Termination", 14: "Offboard", 15: "Stabilized",
             17: "Takeoff", 18: "Land", 20: "Precision Land"}


class Sampler:
    """Reads observables from a running rig; :meth:`new_sample` starts a fresh instant."""

    def __init__(self, orch: Any, dev: dict[str, Any], gcs_results: dict[str, Any] | None = None
                 ) -> None:
        self.orch = orch
        self.dev = dev
        self.gcs_results = gcs_results if gcs_results is not None else {}
        self._cache: dict[str, Any] = {}
        self._texts: list[str] = []
        self._text_cursor = 0
        self._last_chunk_id = 0
        self._texts_seen = 0
        self._last_seen = ""
        self.home_ned: tuple[float, float] = (0.0, 0.0)
        #: the last ``shell`` step's exit status and output (set by the engine)
        self.shell: dict[str, Any] | None = None

    def new_sample(self) -> None:
        self._cache.clear()

    # -- sources ------------------------------------------------------------------------------

    def _call(self, board: str, method: str, *args: Any) -> Any:
        key = f"\0{board}.{method}{args}"
        if key in self._cache:
            return self._cache[key]
        try:
            value = None if board in self.orch.dead else self.orch.call(board, method, *args)
        except BoardDied:
            value = None
        self._cache[key] = value
        return value

    def topic(self, name: str, instance: int = 0) -> dict[str, Any] | None:
        return self._call("fmu", "topic", name, instance)

    def field(self, topic: str, field: str, instance: int = 0) -> Any:
        msg = self.topic(topic, instance)
        return None if msg is None else msg.get(field)

    def io_status(self) -> dict[str, Any] | None:
        st = self._call("io", "status")
        return st if st and st.get("running") else None

    def truth(self) -> Any:
        return self.dev["world"].world.truth()

    def new_texts(self) -> list[str]:
        """STATUSTEXTs that arrived (or grew by a chunk) since the previous call."""
        texts = self.texts()
        n = self._texts_seen
        grew = n > 0 and texts[n - 1] != self._last_seen
        new = texts[n - 1:] if grew else texts[n:]
        self._texts_seen = len(texts)
        self._last_seen = texts[-1] if texts else ""
        return new

    def texts(self) -> list[str]:
        gcs = self.dev.get("gcs")
        if gcs is None:
            return []
        new = gcs.messages("STATUSTEXT", since=self._text_cursor)
        self._text_cursor = gcs.mark()
        for m in new:
            # a long text arrives in 50-character chunks sharing a non-zero id
            chunk_id = getattr(m, "id", 0)
            if chunk_id and getattr(m, "chunk_seq", 0) > 0 and self._last_chunk_id == chunk_id:
                self._texts[-1] += m.text
            else:
                self._texts.append(m.text)
            self._last_chunk_id = chunk_id
        return self._texts

    def alive(self, board: str) -> bool:
        """Not crashed and not hung (a hung board's CPU is halted: ``ctl_hung``)."""
        if board in self.orch.dead or board not in self.orch.handles:
            return False
        return not self.orch.call(board, "hung")

    # -- reading by name ----------------------------------------------------------------------

    def read(self, name: str) -> Any:
        if name in self._cache:
            return self._cache[name]
        base, index = _split_index(name)
        fn = OBSERVABLES.get(base)
        if fn is not None:
            value = fn[1](self)
        elif base.startswith("topic."):
            value = self._generic_topic(base)
        elif base.startswith("gcs.result."):
            value = self.gcs_results.get(base[len("gcs.result."):])
        elif base.startswith(GCS_RATE):
            value = _gcs_rate(self, base[len(GCS_RATE):])
        else:
            raise KeyError(name)
        if index is not None and value is not None:
            try:
                value = value[index]
            except (IndexError, TypeError, KeyError):
                value = None
        self._cache[name] = value
        return value

    def _generic_topic(self, name: str) -> Any:
        parts = name.split(".")[1:]
        instance = 0
        if len(parts) == 3 and parts[1].isdigit():
            instance = int(parts[1])
            parts = [parts[0], parts[2]]
        if len(parts) == 3 and parts[1].endswith("]"):  # a nested message: esc[1].esc_rpm
            field, idx = _split_index(parts[1])
            try:
                return self.field(parts[0], field)[idx][parts[2]]
            except (IndexError, KeyError, TypeError):
                return None
        if len(parts) != 2:
            return None
        return self.field(parts[0], parts[1], instance)


def _split_index(name: str) -> tuple[str, Any]:
    if not name.endswith("]"):
        return name, None
    base, _, idx = name[:-1].partition("[")
    if ":" in idx:
        a, _, b = idx.partition(":")
        return base, slice(int(a) if a else None, int(b) if b else None)
    return base, int(idx)


def is_observable(name: str) -> bool:
    base, _ = _split_index(name)
    if base in OBSERVABLES:
        return True
    if base.startswith("topic."):
        parts = base.split(".")
        return len(parts) in (3, 4) and all(parts[1:])
    if base.startswith(GCS_RATE):
        return len(base) > len(GCS_RATE)
    return base.startswith("gcs.result.") and len(base) > len("gcs.result.")


def _vs(s: Sampler, field: str) -> Any:
    return s.field("vehicle_status", field)


def _nav(s: Sampler) -> Any:
    v = _vs(s, "nav_state")
    return None if v is None else NAV_NAMES.get(int(v), str(v))


def _armed(s: Sampler) -> Any:
    v = _vs(s, "arming_state")
    return None if v is None else v == 2


def _imu_primary(s: Sampler) -> Any:
    m = s.topic("sensors_status_imu")
    if m is None:
        return None
    ids = list(m["device_ids"])
    return ids.index(m["device_id_primary"]) if m["device_id_primary"] in ids else None


def _io_names(key: str) -> Callable[[Sampler], Any]:
    def read(s: Sampler) -> Any:
        st = s.io_status()
        return None if st is None else list(st[key])
    return read


def _io_pwm(s: Sampler) -> Any:
    pwm = s._call("io", "pwm")
    return None if pwm is None else [round(h / 1000.0, 1) for h, _period in pwm]


def _motors(s: Sampler) -> list[float]:
    world = s.dev["world"].world
    return [round(world.escs[ch].pulse_us, 1) for ch in world.airframe.motor_channels]


def _servos(s: Sampler) -> list[float]:
    world = s.dev["world"].world
    return [round(world.escs[ch].pulse_us, 1) for ch in world.airframe.servo_channels]


def _euler_deg(i: int) -> Callable[[Sampler], float]:
    return lambda s: round(math.degrees(s.truth().euler_rad[i]), 2)


def _new_texts(s: Sampler) -> list[str]:
    return s.new_texts()


def _age_s(s: Sampler, topic: str) -> Any:
    m = s.topic(topic)
    if m is None:
        return None
    offset = getattr(s.orch.handles.get("fmu"), "offset", 0)  # a rebooted FMU's time zero
    return round((s.orch.t_ns - offset) / 1e9 - m["timestamp"] / 1e6, 4)


def _tilt_deg(s: Sampler) -> float:
    r, p, _ = s.truth().euler_rad
    return math.degrees(math.acos(max(-1.0, min(1.0, math.cos(r) * math.cos(p)))))


def _on_ground(s: Sampler) -> bool:
    t = s.truth()
    return t.agl_m < 0.3 and math.sqrt(sum(v * v for v in t.vel_ned_m_s)) < 0.3


#: ``gcs.rate_hz.<MESSAGE>``: how many of a MAVLink message the GCS received in the last
#: virtual second (a stream's rate as the ground sees it)
GCS_RATE = "gcs.rate_hz."


def _gcs_rate(s: Sampler, mtype: str) -> Any:
    gcs = s.dev.get("gcs")
    if gcs is None:
        return None
    import bisect

    now = s.orch.t_ns
    if now < 1_000_000_000:
        return None  # not a whole second of history yet
    log = gcs.log
    start = bisect.bisect_right(log, now - 1_000_000_000, key=lambda e: e[0])
    return sum(1 for _, m in log[start:] if m.get_type() == mtype)


def _imu_latency_us(s: Sampler) -> Any:
    m = s.topic("sensor_gyro")
    return None if m is None else m["timestamp"] - m["timestamp_sample"]


def _mavlink_rx_lost(s: Sampler) -> Any:
    links = s._call("fmu", "mavlink")
    if not links:
        return None
    return sum(int(d.get("rx_lost", 0)) for d in links)


def _shell(key: str) -> Callable[[Sampler], Any]:
    return lambda s: None if s.shell is None else s.shell[key]


#: name -> (doc, reader)
OBSERVABLES: dict[str, tuple[str, Callable[[Sampler], Any]]] = {
    "nav_state": ("the commander's mode (vehicle_status.nav_state) by PX4 name: Manual, "
                  "Altitude, Position, Mission, Hold, Return, Land, Takeoff, Descend, "
                  "Termination ...", _nav),
    "armed": ("vehicle_status: the commander is armed", _armed),
    "failsafe": ("vehicle_status.failsafe: a failsafe reaction is active",
                 lambda s: _vs(s, "failsafe")),
    "rc_signal_lost": ("vehicle_status.rc_signal_lost (after COM_RC_LOSS_T)",
                       lambda s: _vs(s, "rc_signal_lost")),
    "preflight_ok": ("vehicle_status.pre_flight_checks_pass",
                     lambda s: _vs(s, "pre_flight_checks_pass")),
    "rc_lost": ("input_rc.rc_lost: the IO reports RC lost", lambda s: s.field("input_rc",
                                                                             "rc_lost")),
    "rc_failsafe": ("input_rc.rc_failsafe: the receiver reports failsafe",
                    lambda s: s.field("input_rc", "rc_failsafe")),
    "rc_channels_us": ("input_rc.values: the channels as the FMU receives them (us)",
                       lambda s: s.field("input_rc", "values")),
    "imu_primary": ("index of the selected IMU in sensors_status_imu (0: MPU6000)",
                    _imu_primary),
    "imu_failovers": ("sensors_status_imu.failover_count",
                      lambda s: s.field("sensors_status_imu", "failover_count")),
    "imu_healthy": ("sensors_status_imu.healthy per instance",
                    lambda s: s.field("sensors_status_imu", "healthy")),
    "baro_healthy": ("sensors_status_baro.healthy per instance",
                     lambda s: s.field("sensors_status_baro", "healthy")),
    "mag_healthy": ("sensors_status_mag.healthy per instance",
                    lambda s: s.field("sensors_status_mag", "healthy")),
    "estimator_fault": ("estimator_status.filter_fault_flags is not zero",
                        lambda s: (None if (v := s.field("estimator_status",
                                                         "filter_fault_flags")) is None
                                   else v != 0)),
    "gps_check_fail": ("estimator_status.gps_check_fail_flags (0: GPS quality checks pass)",
                       lambda s: s.field("estimator_status", "gps_check_fail_flags")),
    "gps_fix": ("sensor_gps.fix_type (3: 3D fix)", lambda s: s.field("sensor_gps", "fix_type")),
    "gps_age_s": ("seconds since the GPS driver last published sensor_gps (FMU clock)",
                  lambda s: _age_s(s, "sensor_gps")),
    "gps_jamming": ("sensor_gps.jamming_indicator",
                    lambda s: s.field("sensor_gps", "jamming_indicator")),
    "landed": ("vehicle_land_detected.landed", lambda s: s.field("vehicle_land_detected",
                                                                "landed")),
    "io.source": ("the IO mixer's source: fmu, override, failsafe, disarmed ...",
                  lambda s: s._call("io", "mixer_source")),
    "io.flags": ("the IO's STATUS flag names (FMU_OK, RC_OK, FAILSAFE, OVERRIDE, "
                 "SAFETY_OFF, ...)", _io_names("flag_names")),
    "io.arming": ("the IO's ARMING flag names (FMU_ARMED, IO_ARM_OK, MANUAL_OVERRIDE_OK, "
                  "INAIR_RESTART_OK, ...)", _io_names("arming_names")),
    "io.alarms": ("the IO's alarm names", _io_names("alarm_names")),
    "io.resets": ("times the IO was reset", lambda s: (st := s._call("io", "status")) and
                  st.get("resets")),
    "io.pwm_us": ("pulse width on each IO PWM pin now (us, 8 values)", _io_pwm),
    "motor_us": ("pulse width each motor's ESC receives (us, one per motor)", _motors),
    "servo_us": ("pulse width each servo receives (us, one per servo: a plane's surfaces in "
                 "the airframe's output order)", _servos),
    "alt_agl_m": ("true height above ground (m)", lambda s: round(s.truth().agl_m, 3)),
    "airspeed_m_s": ("true airspeed (m/s)", lambda s: round(s.truth().airspeed_m_s, 3)),
    "aoa_deg": ("true angle of attack (deg)",
                lambda s: round(math.degrees(s.truth().aoa_rad), 2)),
    "roll_deg": ("true roll angle (deg, right wing down positive)", _euler_deg(0)),
    "pitch_deg": ("true pitch angle (deg, nose up positive)", _euler_deg(1)),
    "vtol_state": ("vtol_vehicle_status.vehicle_vtol_state: 1 to FW, 2 to MC, 3 MC, 4 FW",
                   lambda s: s.field("vtol_vehicle_status", "vehicle_vtol_state")),
    "speed_m_s": ("true ground speed (m/s)",
                  lambda s: math.sqrt(sum(v * v for v in s.truth().vel_ned_m_s))),
    "home_distance_m": ("true horizontal distance from the start point (m)",
                        lambda s: math.hypot(*s.truth().pos_ned_m[:2])),
    "tilt_deg": ("true tilt from level (deg)", _tilt_deg),
    "on_ground": ("truth: below 0.3 m and slower than 0.3 m/s", _on_ground),
    "fmu_alive": ("the FMU runs (not crashed, not hung)", lambda s: s.alive("fmu")),
    "io_alive": ("the IO runs (not crashed, not hung)", lambda s: s.alive("io")),
    "fmu_reboots": ("times the FMU rebooted in this run", lambda s: s.orch.reboots.get("fmu", 0)),
    "home_set": ("the GCS received a HOME_POSITION",
                 lambda s: s.dev["gcs"].last.get("HOME_POSITION") is not None
                 if "gcs" in s.dev else None),
    "gcs.text": ("the STATUSTEXTs the GCS received since the previous sample (use "
                 "'contains': 'within 1 s of X: gcs.text contains \"...\"')", _new_texts),
    "gcs.all_text": ("every STATUSTEXT the GCS received so far", lambda s: s.texts()),
    "t_s": ("virtual time since the start (s)", lambda s: s.orch.t_ns / 1e9),
    # -- added for the bus, board, link and vehicle scenarios -----------------------------------
    "imu_latency_us": ("sensor_gyro (instance 0, the MPU6000): timestamp - timestamp_sample, "
                       "how late the driver published its newest sample (us)", _imu_latency_us),
    "mavlink.rx_lost": ("datagrams the FMU's mavlink receive queues dropped (all links)",
                        _mavlink_rx_lost),
    "shell.status": ("exit status of the last shell step (0: success)", _shell("status")),
    "shell.output": ("what the last shell step printed", _shell("output")),
}
