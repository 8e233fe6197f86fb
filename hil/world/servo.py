"""Hobby servo input: servo-PWM pulse train to a position command in [-1, 1].

What a servo sees is the same pulse train an ESC sees (``set_signal(t_ns, high_ns,
period_ns)``: "from t_ns on, a pulse of high_ns every period_ns"). The pulse width sets the
position: ``centre_us`` (1500) is 0, ``centre_us +- half_span_us`` (1000..2000 us) is -1..+1 of
full throw, clamped beyond (the servo's end stops). A train counts as valid as for the ESC
(0 < high < period, period at most ``max_period_s``, width in ``valid_min_us..valid_max_us``).

Without valid pulses - the line held low (a dead IO), pulses out of range - a digital servo
holds the last commanded position (the usual behaviour of the digital servos on small UAVs;
an analog servo would go limp, which a surface under air load turns into the same "stays
about where it was"). Before the first valid pulse the command is 0 (centre).

The servo's motion (lag, rate limit) is not modelled here: the command goes to a JSBSim
actuator in the airframe's flight-control section, so the surface position the aerodynamics
see is the physical one. Times are integer nanoseconds of the world clock.
"""

from __future__ import annotations

from dataclasses import dataclass

from hil.world.pulse_train import PulseTrainInput

__all__ = ["ServoParams", "ServoInput"]


@dataclass(frozen=True, slots=True)
class ServoParams:
    centre_us: float = 1500.0  # neutral
    half_span_us: float = 500.0  # centre +- this is full throw (-1, +1)
    valid_min_us: float = 800.0  # narrower pulses are ignored
    valid_max_us: float = 2200.0  # wider pulses are ignored
    max_period_s: float = 0.5  # slower trains than this are not a servo signal


class ServoInput(PulseTrainInput):
    """One servo's signal input. ``command`` is the position command in [-1, 1]."""

    __slots__ = ("params", "_cmd", "_max_period_ns")

    def __init__(self, params: ServoParams | None = None) -> None:
        p = params or ServoParams()
        self.params = p
        super().__init__()
        self._cmd = 0.0
        self._max_period_ns = round(p.max_period_s * 1e9)

    @property
    def command(self) -> float:
        return self._cmd

    def update(self, t_ns: int) -> float:
        """Apply inputs stamped at or before t_ns; returns the position command."""
        pend = self._pending
        if pend and pend[0][0] <= t_ns:
            self._apply_due(t_ns)
        return self._cmd

    def _apply(self, ev_t: int, high_ns: int, period_ns: int) -> None:
        p = self.params
        width_us = high_ns * 1e-3
        if not (0 < high_ns < period_ns <= self._max_period_ns
                and p.valid_min_us <= width_us <= p.valid_max_us):
            self._valid = False  # hold the last position
            return
        self._valid = True
        self._width_us = width_us
        x = (width_us - p.centre_us) / p.half_span_us
        self._cmd = 1.0 if x > 1.0 else (-1.0 if x < -1.0 else x)
