"""Boards used only by the lockstep tests (importable by board processes)."""

from board.board import Board


class CrashingBoard(Board):
    """Firmware that divides by zero at a given time (a hard fault)."""

    def __init__(self, name: str = "fmu", seed: int = 0, crash_at_ns: int = 1_000_000) -> None:
        super().__init__(name, seed)
        self.kernel.call_at(crash_at_ns, self.crash_now)

    def crash_now(self) -> None:
        _ = 1 / 0


class PwmBoard(Board):
    """A board whose one PWM output sends 1500 us at 50 Hz from t=0."""

    def __init__(self, name: str = "io", seed: int = 0) -> None:
        super().__init__(name, seed)
        emit = self.expose_output("pwm1", "pwm")
        self.kernel.call_at(0, emit, 0, (1_500_000, 20_000_000))
