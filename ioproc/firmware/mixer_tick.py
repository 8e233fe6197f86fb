"""``mixer_tick``: FMU-loss check, output source, arming decision, mixing, PWM (E14, §3.3-§3.5).

Why this shape: the IO's one job is to decide, every main-loop pass, *who* drives the servos
(the FMU's controls, the pilot's sticks through the RC override, fixed failsafe values, or raw
PWM from the FMU) and *whether* the PWM timers run at all. The decision table and the arming
condition are E14's, restated from io-and-rc.md §3.4; the ramp is :class:`PwmLimit`; the
pulses reach the pins only through :class:`PwmServo`'s timer registers.
"""

from __future__ import annotations

from collections.abc import Callable
from enum import Enum
from typing import Final

from ioproc.firmware.bits import AL, AR, FE, SF
from ioproc.firmware.pwm_out import PwmServo
from ioproc.pages import IoPages
from ioproc.protocol import (
    CONTROL_CHANNELS,
    CONTROL_GROUPS,
    SERVO_COUNT,
    PageNo,
    RcInput,
    Setup,
    Status,
    float_to_reg,
    reg_to_float,
)
from ioproc.pwm_limit import PwmLimit

__all__ = ["FMU_INPUT_DROP_LIMIT_US", "MixSource", "MixerTick"]

#: FMU_INPUT_DROP_LIMIT_US: CONTROLS/DIRECT_PWM silence that counts as FMU loss (§3.3).
FMU_INPUT_DROP_LIMIT_US: Final = 500_000

F: Final = SF
_FLAGS: Final = int(Status.FLAGS)
_ALARMS: Final = int(Status.ALARMS)
_ARMING: Final = int(Setup.ARMING)


class MixSource(Enum):
    """Where the outputs come from this pass (E14 ``source``)."""

    FAILSAFE = "failsafe"
    NONE = "none"  # DIRECT_PWM already in SERVOS
    FMU = "fmu"
    OVERRIDE = "override"
    OVERRIDE_FMU_OK = "override_fmu_ok"


class MixerTick:
    """State the E14 mixer keeps between passes, and the pass itself."""

    def __init__(self, regs: IoPages, pwm: PwmServo, limit: PwmLimit | None = None,
                 sbus_out: Callable[[list[int], int, bool], None] | None = None) -> None:
        self.regs = regs
        self.pwm = pwm
        self.limit = limit or PwmLimit(regs.era)
        self.source = MixSource.FAILSAFE
        self.should_arm = False
        self.always_pwm = False
        #: mixer_servos_armed: the timers are running.
        self.servos_armed = False
        self._sbus_out = sbus_out
        self._fs_cache: dict[int, int] = {}
        self._controls = regs.page(PageNo.CONTROLS)
        self._rc = regs.page(PageNo.RC_INPUT)
        # Live page lists (IoPages never replaces them), looked up once: a pass runs every
        # millisecond, and the page() and status_flags lookups were a fifth of its cost.
        self._status = regs.page(PageNo.STATUS)
        self._setup = regs.page(PageNo.SETUP)
        self._servos = regs.page(PageNo.SERVOS)
        self._actuators = regs.page(PageNo.ACTUATORS)
        self._disarmed = regs.page(PageNo.DISARMED_PWM)
        self._min_pwm = regs.page(PageNo.CONTROL_MIN_PWM)
        self._max_pwm = regs.page(PageNo.CONTROL_MAX_PWM)
        #: (key, outputs, actuator registers) of the last mix. The mixers are pure functions of
        #: the control pages, so a pass whose inputs did not change (the FMU writes controls at
        #: most every ~2.5 ms, the loop runs every 1 ms) reuses the outputs bit for bit.
        self._mix_memo: tuple | None = None
        self._get_control = {
            MixSource.FMU: self._control_fmu,
            MixSource.OVERRIDE: self._control_rc,
            MixSource.OVERRIDE_FMU_OK: self._control_rc_or_fmu,
        }

    # -- mixer input callbacks (E14 mixer_callback) ------------------------------------------
    def _control_fmu(self, group: int, index: int) -> float | None:
        if group >= CONTROL_GROUPS or index >= CONTROL_CHANNELS:
            return None
        return reg_to_float(self._controls[group * CONTROL_CHANNELS + index])

    def _control_rc(self, group: int, index: int) -> float | None:
        bit = group * CONTROL_CHANNELS + index
        if group >= CONTROL_GROUPS or bit >= 16 or not self._rc[RcInput.VALID] & (1 << bit):
            return None
        return reg_to_float(self._rc[RcInput.BASE + index])

    def _control_rc_or_fmu(self, group: int, index: int) -> float | None:
        value = self._control_rc(group, index)
        return self._control_fmu(group, index) if value is None else value

    # -- the pass ----------------------------------------------------------------------------
    def check_fmu(self, now_us: int) -> None:
        """FMU_OK / FMU_LOST from the age of the last CONTROLS or DIRECT_PWM write."""
        last = self.regs.fmu_data_received_us
        status = self._status
        if last is None or now_us - last > FMU_INPUT_DROP_LIMIT_US:
            status[_FLAGS] &= ~F.FMU_OK
            status[_ALARMS] |= AL.FMU_LOST
        else:
            status[_FLAGS] |= F.FMU_OK | F.FMU_INITIALIZED

    def _select_source(self, flags: int, arming: int) -> MixSource:
        override_ok = (flags & F.OVERRIDE and flags & F.RC_OK and flags & F.MIXER_OK
                       and not arming & AR.RC_HANDLING_DISABLED)
        if flags & F.RAW_PWM and flags & F.FMU_OK:
            return MixSource.NONE
        if not flags & F.OVERRIDE and flags & F.FMU_OK and flags & F.MIXER_OK:
            return MixSource.FMU
        if override_ok and not flags & F.FMU_OK and not arming & AR.TERMINATION_FAILSAFE:
            return MixSource.OVERRIDE
        if override_ok and flags & F.FMU_OK:
            return MixSource.OVERRIDE_FMU_OK
        return MixSource.FAILSAFE

    def tick(self, now_us: int) -> None:
        regs = self.regs
        status = self._status
        self.check_fmu(now_us)
        flags, arming = status[_FLAGS], self._setup[_ARMING]
        source = self._select_source(flags, arming)
        should_arm = bool(
            flags & F.INIT_OK and flags & F.SAFETY_OFF
            and ((arming & AR.FMU_ARMED and flags & F.MIXER_OK) or flags & F.RAW_PWM
                 or (arming & AR.FAILSAFE_CUSTOM and not flags & F.FMU_OK)))
        always_pwm = bool(arming & AR.ALWAYS_PWM_ENABLE and flags & F.INIT_OK
                          and flags & F.FMU_OK)
        if (arming & AR.TERMINATION_FAILSAFE and source is MixSource.FAILSAFE and should_arm
                and flags & F.FMU_INITIALIZED):
            regs.arming = arming = arming | AR.FORCE_FAILSAFE  # latched (sticky rule)
        if arming & AR.FORCE_FAILSAFE:
            source = MixSource.FAILSAFE
        if source is MixSource.FAILSAFE:
            status[_FLAGS] |= F.FAILSAFE
        else:
            status[_FLAGS] &= ~F.FAILSAFE
        self.source, self.should_arm, self.always_pwm = source, should_arm, always_pwm

        servos = self._servos
        actuators = self._actuators
        if source is MixSource.FAILSAFE:
            failsafe = regs.page(PageNo.FAILSAFE_PWM)
            cache = self._fs_cache
            for i in range(SERVO_COUNT):
                us = servos[i] = failsafe[i]
                reg = cache.get(us)
                if reg is None:
                    reg = cache[us] = float_to_reg((us - 1500) / 600.0)
                actuators[i] = reg
        elif source is not MixSource.NONE and status[_FLAGS] & F.MIXER_OK:
            outputs, act = self._mix(source)
            mixed = len(outputs)
            pwm = self.limit.calc(should_arm, now_us, self._disarmed, self._min_pwm,
                                  self._max_pwm, outputs)
            for i in range(SERVO_COUNT):
                if i < mixed:
                    servos[i] = pwm[i]
                    actuators[i] = act[i]
                else:
                    servos[i] = 0

        need = (should_arm or always_pwm) and not self._setup[_ARMING] & AR.LOCKDOWN
        pwm_out = self.pwm
        if need and not self.servos_armed:
            pwm_out.arm(True)
            self.servos_armed = True
            status[_FLAGS] |= F.OUTPUTS_ARMED
        elif not need and self.servos_armed:
            pwm_out.arm(False)
            self.servos_armed = False
            status[_FLAGS] &= ~F.OUTPUTS_ARMED
        if self.servos_armed and should_arm:
            self._set_pwm(servos)
            self._sbus(servos, now_us)
        elif self.servos_armed and always_pwm:
            self._set_pwm(self._disarmed)
            self._sbus(servos, now_us)

    def _mix(self, source: MixSource) -> tuple[list[float], list[int]]:
        """The mixer group's outputs and their ACTUATORS registers, memoised on the inputs."""
        group = self.regs.mixer.group
        if source is MixSource.FMU:
            key: tuple = (source, group, group.version, tuple(self._controls))
        else:
            key = (source, group, group.version, tuple(self._controls), tuple(self._rc))
        memo = self._mix_memo
        if memo is not None and memo[0] == key:
            return memo[1], memo[2]
        outputs = group.mix(self._get_control[source], SERVO_COUNT)
        act = [float_to_reg(v) for v in outputs]
        self._mix_memo = (key, outputs, act)
        return outputs, act

    def _set_pwm(self, pulses: list[int]) -> None:
        """up_pwm_servo_set for every output, skipping the (unobservable) unchanged ones here
        rather than in a call per output."""
        pwm_out = self.pwm
        shadow = pwm_out._ccr
        for i in range(SERVO_COUNT):
            us = pulses[i]
            if shadow[i] != (us - 1 if us > 0 else 0):
                pwm_out.set(i, us)

    def _sbus(self, servos: list[int], now_us: int) -> None:
        if self._sbus_out is None:
            return
        features = self.regs.page(PageNo.SETUP)[Setup.FEATURES]
        if features & (FE.SBUS1_OUT | FE.SBUS2_OUT):
            self._sbus_out(servos, now_us, bool(features & FE.SBUS2_OUT))
