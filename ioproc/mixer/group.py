"""MixerGroup: the ordered list of mixers whose outputs fill the IO's output array."""

from __future__ import annotations

from ioproc.mixer.base import ControlSource, Mixer


class MixerGroup:
    """Mixers in load order; mixer k's outputs follow mixer k-1's (PX4 MixerGroup)."""

    def __init__(self) -> None:
        self.mixers: list[Mixer] = []
        #: bumped on every change, so that callers may memoise :meth:`mix` on their inputs
        self.version = 0

    def add(self, mixer: Mixer) -> None:
        self.mixers.append(mixer)
        self.version += 1

    def reset(self) -> None:
        """Drop every mixer (mixer upload action 0)."""
        self.mixers.clear()
        self.version += 1

    def __len__(self) -> int:
        return len(self.mixers)

    @property
    def output_count(self) -> int:
        return sum(m.output_count for m in self.mixers)

    def mix(self, source: ControlSource, space: int) -> list[float]:
        """Outputs of all mixers, stopping when ``space`` outputs are filled (IO: 8)."""
        outputs: list[float] = []
        for mixer in self.mixers:
            if len(outputs) >= space:
                break
            outputs += mixer.mix(source, space - len(outputs))
        return outputs
