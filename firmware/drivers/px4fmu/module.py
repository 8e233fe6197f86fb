"""``fmu``: the shell face of the FMU's own PWM outputs (PX4's ``fmu`` driver, ``mode_pwm``).

``fmu start`` (or ``fmu mode_pwm``) takes the board's FMU-side PWM outputs from its spec
(AUX1..AUX6 on a Pixhawk 1: TIM1 CH4..CH1 and TIM4 CH2..CH3) and the timers from the board
(``system.hw.timers``); ``mixer load /dev/pwm_output1 FILE`` (``/dev/px4fmu``) hands it a mixer.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, ClassVar

from firmware.drivers.px4fmu.output import AuxOutput
from firmware.platform.module import ModuleBase, ModuleError, UsageError
from firmware.platform.params import ParamDef

if TYPE_CHECKING:
    from firmware.system import System

__all__ = ["FmuModule", "PARAMS"]

_GROUP = "PWM Outputs"
PARAMS: tuple[ParamDef, ...] = (
    ParamDef("PWM_AUX_RATE", "INT32", 50, min=50, max=400, unit="Hz", group=_GROUP,
             short="PWM rate of the FMU's AUX outputs",
             long="50 Hz for servos; ESCs on AUX may take up to 400 Hz."),
    ParamDef("PWM_AUX_MIN", "INT32", 1000, min=800, max=1400, unit="us", group=_GROUP,
             short="Minimum PWM of the AUX outputs (mixer output -1)"),
    ParamDef("PWM_AUX_MAX", "INT32", 2000, min=1600, max=2200, unit="us", group=_GROUP,
             short="Maximum PWM of the AUX outputs (mixer output +1)"),
    ParamDef("PWM_AUX_DISARMED", "INT32", 0, min=0, max=2200, unit="us", group=_GROUP,
             short="AUX PWM while disarmed",
             long="0 sends no pulses while disarmed: servos hold where they are and an ESC "
                  "on AUX stays off."),
)


class FmuModule(ModuleBase):
    """The FMU's PWM outputs."""

    NAME: ClassVar[str] = "fmu"
    DESCRIPTION: ClassVar[str] = "the FMU's own PWM outputs (AUX1..AUX6 on a Pixhawk 1)"
    USAGE: ClassVar[tuple[str, ...]] = (
        "mode_pwm                      start with every FMU PWM output (as start)",
        "mixer <file>                  load a mixer (what mixer load /dev/pwm_output1 runs)",
    )
    PARAMS: ClassVar[tuple[ParamDef, ...]] = PARAMS

    def __init__(self, system: System, args: Sequence[str] = ()) -> None:
        super().__init__(system, args)
        self.output: AuxOutput | None = None

    @classmethod
    def instantiate(cls, system: System, args: Sequence[str]) -> ModuleBase:
        for arg in args:
            if arg != "mode_pwm":
                raise UsageError(f"unknown option {arg}")
        return cls(system, args)

    def _start(self) -> None:
        hw: Any = getattr(self.system, "hw", None)
        timers = getattr(hw, "timers", None)
        spec = self.system.board or getattr(hw, "spec", None)
        if not timers or spec is None or not spec.pwm:
            raise ModuleError(f"{self.name}: this board has no FMU PWM outputs")
        names = sorted({o.timer for o in spec.pwm}, key=lambda t: min(
            o.group for o in spec.pwm if o.timer == t))
        missing = [t for t in names if t not in timers]
        if missing:
            raise ModuleError(f"{self.name}: timers {', '.join(missing)} not on this board")
        index = {t: i for i, t in enumerate(names)}
        channels = [(index[o.timer], o.channel) for o in spec.pwm]
        self.output = AuxOutput(self, [timers[t] for t in names], channels,
                                [spec.timers_hz[t] for t in names],
                                [t in ("TIM1", "TIM8") for t in names],
                                [index[o.timer] for o in spec.pwm])
        self.add_work_item(self.output)
        self.output.start()

    def _stop(self) -> None:
        if self.output is not None:
            self.output.stop()
            self.output = None

    def status_lines(self) -> list[str]:
        return self.output.status_lines() if self.output is not None else []

    def custom_command(self, args: list[str]) -> int:
        if args[0] != "mixer":
            return super().custom_command(args)
        if self.output is None:
            raise ModuleError(f"{self.name}: not started")
        if len(args) != 2:
            raise UsageError("mixer needs one file name")
        path = args[1]
        try:
            text = self.system.resolve_path(path).read_text(encoding="latin-1")
            n = self.output.load_mixer(text, path)
        except (OSError, ValueError) as exc:  # MixerParseError is a ValueError naming the line
            self.print(f"{self.name}: mixer {path}: {exc}")
            return 1
        self.info(f"mixer {path} loaded ({n} outputs)")
        return 0
