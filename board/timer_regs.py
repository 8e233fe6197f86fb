"""The STM32 general-purpose timer's register map and bits (RM0090 / RM0041 "TIMx registers").

Data apart from the behaviour in :mod:`board.timer`, as the peripherals keep their register
tables: the model reads names and bits from here; firmware keeps its own copies of the bits it
writes, as a real driver's header does.
"""

from __future__ import annotations

from typing import Final

__all__ = ["REGISTERS", "OFFSETS", "CCR_INDEX", "cc_if", "cc_of"]

#: Register map: offset -> (name, reset value; None = depends on the counter width).
REGISTERS: Final[dict[int, tuple[str, int | None]]] = {
    0x00: ("CR1", 0), 0x04: ("CR2", 0), 0x08: ("SMCR", 0), 0x0C: ("DIER", 0),
    0x10: ("SR", 0), 0x14: ("EGR", 0), 0x18: ("CCMR1", 0), 0x1C: ("CCMR2", 0),
    0x20: ("CCER", 0), 0x24: ("CNT", 0), 0x28: ("PSC", 0), 0x2C: ("ARR", None),
    0x30: ("RCR", 0), 0x34: ("CCR1", 0), 0x38: ("CCR2", 0), 0x3C: ("CCR3", 0),
    0x40: ("CCR4", 0), 0x44: ("BDTR", 0),
}
OFFSETS: Final = {name: off for off, (name, _) in REGISTERS.items()}
CCR_INDEX: Final = {"CCR1": 0, "CCR2": 1, "CCR3": 2, "CCR4": 3}  # Timer.write fast path

# Bit positions (RM0090 / RM0041).
CR1_CEN: Final = 1
CR1_UDIS: Final = 2
CR1_URS: Final = 4
CR1_OPM: Final = 8
CR1_DIR: Final = 0x10
CR1_CMS: Final = 0x60
CR1_ARPE: Final = 0x80
DIER_UIE = SR_UIF = EGR_UG = 1
BDTR_MOE: Final = 1 << 15
OCM_FORCE_LOW: Final = 4
OCM_FORCE_HIGH: Final = 5
OCM_PWM1: Final = 6
OCM_PWM2: Final = 7
UNMODELLED_CR1: Final = CR1_UDIS | CR1_OPM | CR1_DIR | CR1_CMS


def cc_if(ch: int) -> int:
    """SR.CCxIF / DIER.CCxIE / EGR.CCxG bit of channel ``ch`` (1..4)."""
    return 1 << ch


def cc_of(ch: int) -> int:
    """SR.CCxOF bit of channel ``ch`` (1..4)."""
    return 1 << (ch + 8)
