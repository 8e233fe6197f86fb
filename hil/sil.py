"""An in-process closed loop for developing and testing the flight stack.

World (JSBSim) -> the FMU board's Environment -> sensors and drivers -> flight stack ->
``actuator_controls_0`` -> mixer -> PWM -> world ESCs, all in one process and one clock.

The IO coprocessor is *replaced* here by a direct mixer (the same mixer code the IO runs, fed
the FMU's actuator controls without the serial link, the IO firmware's PWM limit state machine
or its failsafe). That is what makes this a development harness and not the emulator:
``hil run`` flies through the real IO board over the emulated 1.5 Mbit/s link.
"""

from __future__ import annotations

import math
from typing import Any, Callable

from fmu.board import FmuV2Board
from common.truth import TRUTH_FIELDS
from hil.world import World
from ioproc.mixer import parse_mixer_text
from ioproc.mixer.group import MixerGroup
from firmware.platform.uorb import Subscription

__all__ = ["Sil", "QUAD_X_MIXER"]

QUAD_X_MIXER = "R: 4x 10000 10000 10000 0\n"
NS_PER_S = 1_000_000_000


class Sil:
    """World + FMU board + direct mixer, stepped together at the world rate."""

    def __init__(self, seed: int = 0, mixer_text: str = QUAD_X_MIXER,
                 fmu: FmuV2Board | None = None, world: World | None = None,
                 pwm_min_us: int = 1000, pwm_max_us: int = 2000, pwm_disarmed_us: int = 900,
                 **fmu_kwargs: Any) -> None:
        self.world = world if world is not None else World(seed=seed)
        self.fmu = fmu if fmu is not None else FmuV2Board(seed=seed, **fmu_kwargs)
        self.mixer = MixerGroup()
        for m in parse_mixer_text(mixer_text):
            self.mixer.add(m)
        orb = self.fmu.platform.orb
        self._controls = Subscription(orb, "actuator_controls_0")
        self._armed = Subscription(orb, "actuator_armed")
        self._ctl = [[0.0] * 8 for _ in range(4)]
        self._is_armed = False
        self.pwm_min, self.pwm_max, self.pwm_disarmed = pwm_min_us, pwm_max_us, pwm_disarmed_us
        self.pwm_us = [pwm_disarmed_us] * 8
        self.hooks: list[Callable[[Sil], None]] = []
        self._feed_truth()

    @property
    def t_ns(self) -> int:
        return self.world.t_ns

    def _feed_truth(self) -> None:
        truth = self.world.truth()
        self.fmu.env.update_from_truth(truth.t_ns, {k: getattr(truth, k) for k in TRUTH_FIELDS})
        self.fmu._power_v, self.fmu._power_a = truth.battery_v, truth.battery_a

    def _source(self, group: int, index: int) -> float:
        return self._ctl[group][index] if 0 <= group < 4 and 0 <= index < 8 else 0.0

    def step(self) -> None:
        """One world step: the FMU runs to the world's time, the mixer sets the ESCs."""
        w = self.world
        w.step()
        self._feed_truth()
        self.fmu.kernel.run(w.t_ns)
        msg = self._controls.update()
        if msg is not None:
            self._ctl[0] = list(msg.control)
        armed = self._armed.update()
        if armed is not None:
            self._is_armed = bool(armed.armed)
        if self._is_armed:
            outs = self.mixer.mix(self._source, 8)
            span = self.pwm_max - self.pwm_min
            for i, o in enumerate(outs):
                if math.isnan(o):
                    o = -1.0
                self.pwm_us[i] = round(self.pwm_min + (max(-1.0, min(1.0, o)) + 1.0) * 0.5 * span)
        else:
            self.pwm_us = [self.pwm_disarmed] * 8
        for i in range(4):
            w.set_pwm(i, w.t_ns, self.pwm_us[i] * 1000, 2_500_000)
        for hook in self.hooks:
            hook(self)

    def run(self, seconds: float) -> None:
        end = self.world.t_ns + int(seconds * NS_PER_S)
        while self.world.t_ns < end:
            self.step()
