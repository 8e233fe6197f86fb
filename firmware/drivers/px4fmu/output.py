"""The FMU's own PWM outputs (PX4's ``fmu`` driver in ``mode_pwm``): the AUX servo rail.

On a Pixhawk 1 with the IO, the MAIN outputs belong to the IO and the FMU drives AUX1..AUX6
itself from TIM1 (AUX1-4) and TIM4 (AUX5-6). A VTOL puts its plane's surfaces and pusher
there (``mixer load /dev/pwm_output1 FILE``), mixed on the FMU from control groups 0 and 1.

The driver is the IO's pipeline run on the FMU, as PX4 runs the same libraries on both
processors: the mixer library (:mod:`ioproc.mixer`), the pwm_limit state machine (disarmed
values, then a ramp to PWM_AUX_MIN on arming) and the timer layer (:class:`PwmServo`, register
level). It runs when a control group it mixes is published (at most every
``UPDATE_INTERVAL_US``) and every ``BACKSTOP_INTERVAL_US`` besides, so that disarming reaches
the pins even when the controllers have stopped publishing.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Final

from firmware.platform.workqueue import WorkItem
from ioproc.firmware.pwm_out import PwmServo
from ioproc.mixer import MixerGroup, parse_mixer_text
from ioproc.pwm_limit import PwmLimit

if TYPE_CHECKING:
    from firmware.drivers.px4fmu.module import FmuModule

__all__ = ["AuxOutput", "BACKSTOP_INTERVAL_US", "UPDATE_INTERVAL_US"]

#: controls are taken at most at 400 Hz (PX4's fmu driver's default update limit)
UPDATE_INTERVAL_US: Final = 2_500
#: and the outputs recomputed at least at 10 Hz (arming changes, stale controls)
BACKSTOP_INTERVAL_US: Final = 100_000
#: control groups the FMU mixes: 0 (attitude) and 1 (the VTOL's fixed-wing controls)
GROUPS: Final = 2


class AuxOutput(WorkItem):
    """Mixer, pwm_limit and timers of the FMU's outputs."""

    def __init__(self, module: FmuModule, timers: Sequence[Any],
                 channels: Sequence[tuple[int, int]], clocks_hz: Sequence[int],
                 advanced: Sequence[bool], rate_groups: Sequence[int]) -> None:
        super().__init__(module.platform, "fmu", "wq:hp_default")
        self.module = module
        self.servo = PwmServo(timers, channels, clocks_hz, advanced)
        self.n_outputs = len(channels)
        #: which timer (rate group) each output is on
        self.rate_groups = tuple(rate_groups)
        self.group = MixerGroup()
        self.mixer_path = ""
        self.limit = PwmLimit()
        self.armed = False
        self.pwm_us: list[int] = [0] * self.n_outputs
        self._controls: list[list[float]] = [[0.0] * 8 for _ in range(GROUPS)]
        self.sub_controls = [module.subscribe_callback(self, f"actuator_controls_{g}",
                                                       interval_us=UPDATE_INTERVAL_US)
                             for g in range(GROUPS)]
        self.sub_armed = module.subscribe("actuator_armed")
        self.pub_outputs = module.advertise("actuator_outputs", None)
        self.msg_outputs = module.platform.orb.new("actuator_outputs")
        self.perf_cycle = module.perf_alloc("elapsed", "cycle")
        self.cpu_cost_ns = 25_000

    # -- set-up -----------------------------------------------------------------------------

    def start(self) -> None:
        self.servo.init()
        rate = int(self.module.param("PWM_AUX_RATE"))
        for g in sorted(set(self.rate_groups)):
            self.servo.set_rate(g, rate)
        self.schedule_on_interval(BACKSTOP_INTERVAL_US)
        self.schedule_now()  # the disarmed values from the start

    def stop(self) -> None:
        self.servo.arm(False)

    def load_mixer(self, text: str, path: str) -> int:
        """Replace the mixer with ``text``'s; returns its output count (``MixerParseError``
        names the line, as ``mixer load`` reports it)."""
        group = MixerGroup()
        for m in parse_mixer_text(text):
            group.add(m)
        if not len(group):
            raise ValueError("no mixer in the file (lines 'M:', 'R:' or 'Z:')")
        self.group = group
        self.mixer_path = path
        return min(group.output_count, self.n_outputs)

    # -- the cycle --------------------------------------------------------------------------

    def _source(self, group: int, index: int) -> float | None:
        return self._controls[group][index] if 0 <= group < GROUPS and 0 <= index < 8 else None

    def run(self) -> None:
        self.perf_cycle.begin()
        for g, sub in enumerate(self.sub_controls):
            msg = sub.update()
            if msg is not None:
                self._controls[g] = list(msg.control)
        armed_msg = self.sub_armed.copy()
        armed = bool(armed_msg is not None and armed_msg.armed and not armed_msg.lockdown
                     and not armed_msg.manual_lockdown)
        if armed != self.armed:
            self.servo.arm(armed or self.module.param("PWM_AUX_DISARMED") > 0)
            self.armed = armed
        n = self.n_outputs
        mixed = self.group.mix(self._source, n) if len(self.group) else []
        outputs = mixed + [0.0] * (n - len(mixed))
        p = self.module.param
        disarmed = [int(p("PWM_AUX_DISARMED"))] * n
        lo = [int(p("PWM_AUX_MIN"))] * n
        hi = [int(p("PWM_AUX_MAX"))] * n
        now_us = self.platform.hrt.absolute_time()
        pwm = self.limit.calc(armed, now_us, disarmed, lo, hi, outputs)
        for i in range(n):
            # outputs the mixer does not drive get no pulse (PX4: unused channels stay off)
            us = pwm[i] if i < len(mixed) else 0
            self.servo.set(i, us)
            self.pwm_us[i] = us
        m = self.msg_outputs
        m.timestamp = now_us
        m.noutputs = n
        for i in range(n):
            m.output[i] = float(self.pwm_us[i])
        self.pub_outputs.publish(m)
        self.perf_cycle.end()

    def status_lines(self) -> list[str]:
        rates = sorted(set(self.servo.rates_hz))
        return [f"mixer: {self.mixer_path or 'none'} ({self.group.output_count} outputs)",
                f"armed: {self.armed}, pwm_limit {self.limit.state.name}, rate {rates} Hz",
                "pwm (us): " + " ".join(str(v) for v in self.pwm_us)]
