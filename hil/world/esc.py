"""Electronic speed controller (ESC) model: servo-PWM input to a motor throttle.

What the ESC sees is a pulse train on its signal wire. The model takes the train as the PWM
timer produces it: ``set_signal(t_ns, high_ns, period_ns)`` says "from t_ns on, a pulse of
high_ns every period_ns" (what the IO's timer compare registers do until changed). A train is
valid when 0 < high < period, the period is at most the signal timeout, and the pulse width is
inside [valid_min_us, valid_max_us] (800..2200 us by default). Anything else - the line held low
(a dead IO, ``high_ns == 0``), held high, or pulses out of range (noise, OneShot on a PWM ESC) -
is "no valid pulses", and the ESC reacts like a real one (BLHeli/SimonK behaviour):

* it keeps the last throttle for ``signal_timeout_s`` (0.5 s), then stops the motor and
  disarms;
* it arms only after ``arm_low_s`` of valid pulses below ``start_us`` (throttle low); a
  disarmed ESC ignores higher pulses, so a motor never restarts by itself when the signal comes
  back at flight throttle after a loss;
* calibrated throttle: ``pwm_min_us`` (1000) is 0, ``pwm_max_us`` (2000) is 1; below
  ``start_us`` (1075, PX4's PWM_MIN) the motor does not turn (throttle 0);
* the output follows the command through a first-order lag with time constant ``tau_s``
  (exactly discretised, so the output reaches 63.2 % of a step after tau). JSBSim's motor and
  propeller model adds the rotor's own spin-up on top (about 50 ms at hover for the F450);
* when the ESC stops (timeout) the drive is cut at once (output 0, the rotor then spins down
  in JSBSim).

Times are integer nanoseconds of the world clock. ``update(t_ns)`` is called once per world step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from hil.world.pulse_train import PulseTrainInput

__all__ = ["EscParams", "Esc"]

_NEVER = 1 << 62


@dataclass(frozen=True, slots=True)
class EscParams:
    pwm_min_us: float = 1000.0  # calibrated throttle 0
    pwm_max_us: float = 2000.0  # calibrated throttle 1
    start_us: float = 1075.0  # pulses below this: motor does not turn (and count as "low")
    valid_min_us: float = 800.0  # narrower pulses are rejected as invalid
    valid_max_us: float = 2200.0  # wider pulses are rejected as invalid
    signal_timeout_s: float = 0.5  # no valid pulse for this long: stop and disarm
    arm_low_s: float = 0.1  # valid low pulses needed to arm; 0 arms on any valid pulse
    tau_s: float = 0.02  # first-order lag of the throttle output


class Esc(PulseTrainInput):
    """One ESC. ``throttle`` is its output in [0, 1] (fraction of battery voltage to the motor)."""

    __slots__ = (
        "params",
        "dt_ns",
        "_alpha",
        "_armed",
        "_cmd",
        "_y",
        "_deadline_ns",
        "_deadline_kind",
        "_timeout_ns",
        "_arm_ns",
        "_span_us",
    )

    def __init__(self, dt_ns: int, params: EscParams | None = None) -> None:
        p = params or EscParams()
        self.params = p
        self.dt_ns = dt_ns
        self._alpha = 1.0 - math.exp(-dt_ns * 1e-9 / p.tau_s) if p.tau_s > 0 else 1.0
        super().__init__()
        self._armed = False
        self._cmd = 0.0
        self._y = 0.0
        self._deadline_ns = _NEVER
        self._deadline_kind = 0  # 0 none, 1 signal timeout, 2 arming
        self._timeout_ns = round(p.signal_timeout_s * 1e9)
        self._arm_ns = round(p.arm_low_s * 1e9)
        self._span_us = p.pwm_max_us - p.pwm_min_us

    # -- state ----------------------------------------------------------------------------
    @property
    def throttle(self) -> float:
        """Output throttle in [0, 1] after the lag."""
        return self._y

    @property
    def command(self) -> float:
        """Throttle the ESC is steering towards (before the lag)."""
        return self._cmd

    @property
    def armed(self) -> bool:
        return self._armed

    # -- stepping -------------------------------------------------------------------------
    def update(self, t_ns: int) -> float:
        """Apply inputs stamped at or before t_ns, run timers, advance the lag by one dt."""
        if self._pending and self._pending[0][0] <= t_ns:
            self._apply_due(t_ns)  # a deadline between an event and now fires below
        if t_ns >= self._deadline_ns:
            self._deadline(t_ns)
        u = self._cmd
        y = self._y
        if y != u:
            y += (u - y) * self._alpha
            if -1e-12 < u - y < 1e-12:
                y = u
            self._y = y
        return y

    def _apply(self, ev_t: int, high_ns: int, period_ns: int) -> None:
        p = self.params
        width_us = high_ns * 1e-3
        valid = (
            0 < high_ns < period_ns
            and period_ns <= self._timeout_ns
            and p.valid_min_us <= width_us <= p.valid_max_us
        )
        if not valid:
            if self._valid or self._deadline_kind == 2:
                # last valid pulse was (about) now: keep the throttle until the timeout
                self._valid = False
                self._deadline_ns = ev_t + self._timeout_ns
                self._deadline_kind = 1
            return
        was_valid = self._valid
        self._valid = True
        self._width_us = width_us
        low = width_us < p.start_us
        if self._armed:
            self._deadline_ns = _NEVER
            self._deadline_kind = 0
            self._cmd = self._throttle_of(width_us)
        elif low:
            if not (was_valid and self._deadline_kind == 2):
                self._deadline_ns = ev_t + self._arm_ns
                self._deadline_kind = 2
        else:
            # disarmed and not low: ignore, and restart any arming sequence
            self._deadline_ns = _NEVER
            self._deadline_kind = 0

    def _deadline(self, t_ns: int) -> None:
        kind = self._deadline_kind
        self._deadline_ns = _NEVER
        self._deadline_kind = 0
        if kind == 1:  # signal lost for the timeout: stop, cut the drive, disarm
            self._armed = False
            self._cmd = 0.0
            self._y = 0.0
        elif kind == 2 and self._valid and self._width_us < self.params.start_us:
            self._armed = True
            self._cmd = self._throttle_of(self._width_us)

    def _throttle_of(self, width_us: float) -> float:
        p = self.params
        if width_us < p.start_us:
            return 0.0
        x = (width_us - p.pwm_min_us) / self._span_us
        return 1.0 if x > 1.0 else (0.0 if x < 0.0 else x)
