"""Mixer building blocks of PX4's mixer library as the E14 IO runs it: scaler, null, simple.

A mixer turns normalized control inputs (group, index) into normalized outputs (-1..1 for the
PWM limit stage). Inputs are fetched through a callback at mix time, as in PX4, so the IO can
switch the source (FMU controls, RC override, failsafe zeros) without rebuilding mixers.

Values in mixer text are integers x10000 (10000 = 1.0). PX4 computes in float32; this model
uses Python floats, so a result sitting exactly on a truncation boundary may differ by one
microsecond after PWM conversion (documented gap).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

#: get_control(group, index) -> value, or None when the source does not provide that control.
ControlSource = Callable[[int, int], float | None]


def zero_source(group: int, index: int) -> float:
    """All controls zero: used for mixer-derived failsafe values (io-and-rc.md §3.4)."""
    return 0.0


def fetch(source: ControlSource, group: int, index: int) -> float:
    """One input; an unavailable control leaves E14's variable uninitialised - we model 0."""
    value = source(group, index)
    return 0.0 if value is None else value


@dataclass(frozen=True)
class Scaler:
    """mixer_scaler_s: piecewise-linear gain with offset and output limits (all x1.0 units)."""

    negative_scale: float = 1.0
    positive_scale: float = 1.0
    offset: float = 0.0
    min_output: float = -1.0
    max_output: float = 1.0

    @classmethod
    def from_ints(cls, neg: int, pos: int, offset: int, lower: int, upper: int) -> Scaler:
        """From the x10000 integers of an ``O:``/``S:`` line."""
        return cls(neg / 10000.0, pos / 10000.0, offset / 10000.0, lower / 10000.0,
                   upper / 10000.0)

    def __call__(self, value: float) -> float:
        out = value * (self.negative_scale if value < 0.0 else self.positive_scale) + self.offset
        if out > self.max_output:
            return self.max_output
        if out < self.min_output:
            return self.min_output
        return out

    def check(self) -> int:
        """PX4 Mixer::scale_check: 0 = sane, else the number of the first failed rule (1..5)."""
        if self.offset > 1.001:
            return 1
        if self.offset < -1.001:
            return 2
        if self.min_output > self.max_output:
            return 3
        if self.min_output < -1.001:
            return 4
        if self.max_output > 1.001:
            return 5
        return 0


class Mixer:
    """A mixer produces ``output_count`` consecutive outputs of the group's output array."""

    output_count: int = 1

    def mix(self, source: ControlSource, space: int) -> list[float]:
        """Outputs for the current inputs; at most ``space`` values (the group's room left)."""
        raise NotImplementedError


class NullMixer(Mixer):
    """``Z:``: holds an output slot and drives it to 0.0 (E14; NaN only from 2017 on)."""

    def mix(self, source: ControlSource, space: int) -> list[float]:
        return [0.0] if space > 0 else []

    def __repr__(self) -> str:
        return "NullMixer()"


@dataclass(frozen=True)
class SimpleInput:
    """One ``S:`` line: which control to read and how to scale it."""

    group: int
    index: int
    scaler: Scaler


class SimpleMixer(Mixer):
    """``M: n`` + ``O:`` + n x ``S:``: output = O(sum of S_i(control_i)), one output."""

    def __init__(self, output_scaler: Scaler, inputs: tuple[SimpleInput, ...]) -> None:
        self.output_scaler = output_scaler
        self.inputs = inputs

    def mix(self, source: ControlSource, space: int) -> list[float]:
        if space < 1:
            return []
        total = 0.0
        for inp in self.inputs:
            total += inp.scaler(fetch(source, inp.group, inp.index))
        return [self.output_scaler(total)]

    def check(self) -> int:
        """0 if every scaler is sane (PX4 SimpleMixer::check), else the first failure code."""
        for code in [self.output_scaler.check()] + [i.scaler.check() for i in self.inputs]:
            if code:
                return code
        return 0

    def __repr__(self) -> str:
        return f"SimpleMixer(O={self.output_scaler}, inputs={list(self.inputs)})"
