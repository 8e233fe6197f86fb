"""Wires between boards and the world, declared as data beside the board specs.

A wire joins an output port to an input port: ``Wire(("io", "pwm1"), ("world", "esc1"))``. A
UART link is two wires, one per direction. ``"world"`` names the orchestrator's world (JSBSim,
ESCs, RC receiver, battery); every other name is a board.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

__all__ = ["Wire", "WORLD", "uart_link", "PIXHAWK1"]

WORLD: Final = "world"


@dataclass(frozen=True)
class Wire:
    src: tuple[str, str]   # (board or "world", output port)
    dst: tuple[str, str]   # (board or "world", input port)
    about: str = ""

    def __str__(self) -> str:
        return f"{self.src[0]}.{self.src[1]} -> {self.dst[0]}.{self.dst[1]}"


def uart_link(a: tuple[str, str], b: tuple[str, str], about: str = "") -> list[Wire]:
    """Both directions of a UART connection (TX of each side to RX of the other)."""
    return [Wire(a, b, about), Wire(b, a, about)]


#: The Pixhawk 1 (FMUv2 + IOv2) system: what is soldered and plugged together.
PIXHAWK1: Final[list[Wire]] = [
    *uart_link(("fmu", "io_link"), ("io", "fmu_link"),
               "FMU USART6 <-> IO USART2, 1.5 Mbit/s 8N1 (PX4IO protocol)"),
    Wire((WORLD, "truth"), ("fmu", "truth"),
         "physical quantities at the FMU's sensors (specific force, rates, field, pressure)"),
    Wire((WORLD, "battery"), ("fmu", "power"), "battery voltage and current at the power module"),
    Wire((WORLD, "rc_sbus"), ("io", "sbus_in"), "S.BUS receiver -> IO USART3 RX (inverted)"),
    Wire((WORLD, "rc_dsm"), ("io", "dsm_in"), "Spektrum satellite -> IO USART1 RX"),
    Wire((WORLD, "rc_ppm"), ("io", "ppm_in"), "PPM-sum receiver -> IO input capture pin"),
    Wire((WORLD, "safety_button"), ("io", "safety_button"), "safety switch button"),
    *[Wire(("io", f"pwm{i}"), (WORLD, f"esc{i}"), f"IO main output {i} -> ESC {i}")
      for i in range(1, 9)],
]
