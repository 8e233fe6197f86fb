"""Wires between boards and the world, declared as data beside the board specs.

A wire joins an output port to an input port: ``Wire(("io", "pwm1"), ("world", "esc1"))``. A
UART link is two wires, one per direction. ``"world"`` names the orchestrator's world (JSBSim,
ESCs, RC receiver, battery); every other name is a board.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

__all__ = ["Wire", "WORLD", "uart_link", "PIXHAWK1", "CAN_ESC_WIRES", "CAN_ESC_NODES",
           "COMPANION", "COMPANION_WIRES", "FMU_AUX_WIRES", "with_can_escs", "with_fmu_aux"]

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

#: DroneCAN ESC nodes on the FMU's CAN1, one per motor of the quadrotor, with fixed node IDs
#: 11..14 (as a user configures them, so their IDs do not depend on allocation order):
#: ``FmuV2Board(uavcan_nodes=...)`` entries.
CAN_ESC_NODES: Final[tuple[str, ...]] = tuple(f"esc{i}@{10 + i}" for i in range(1, 5))

#: The motors on CAN ESCs: each ESC node's motor output (``can_escN``, the pulse train
#: equivalent to its RawCommand element) drives the world's ESC/motor ``escN``.
CAN_ESC_WIRES: Final[list[Wire]] = [
    Wire(("fmu", f"can_esc{i}"), (WORLD, f"esc{i}"), f"CAN ESC {i} (node {10 + i}) -> motor {i}")
    for i in range(1, 5)]


def with_can_escs(wiring: list[Wire]) -> list[Wire]:
    """``wiring`` with motors 1..4 moved from the IO's main outputs to the CAN ESCs: the IO's
    ``pwm1..4`` are unplugged (nothing else drives those motors), ``pwm5..8`` stay."""
    moved = {w.dst for w in CAN_ESC_WIRES}
    return [w for w in wiring if not (w.src[0] == "io" and w.dst in moved)] + CAN_ESC_WIRES


#: The FMU's AUX outputs 1..6 (its own timers, PX4's ``fmu`` driver) to the world's servo and
#: ESC inputs ``aux1..aux6``: a VTOL's surfaces and pusher. Only an airframe whose world model
#: has AUX channels gets them (:func:`with_fmu_aux`), so the quadrotor's and the plane's
#: systems, and their traces, stay as they were.
FMU_AUX_WIRES: Final[list[Wire]] = [
    Wire(("fmu", f"aux{i}"), (WORLD, f"aux{i}"), f"FMU AUX output {i} -> servo/ESC {i}")
    for i in range(1, 7)]


def with_fmu_aux(wiring: list[Wire], n_aux: int) -> list[Wire]:
    """``wiring`` plus the first ``n_aux`` FMU AUX wires (the channels the world model uses)."""
    return wiring + FMU_AUX_WIRES[:max(0, min(n_aux, len(FMU_AUX_WIRES)))]


#: The companion computer's board name (companion.board.CompanionBoard).
COMPANION: Final = "companion"

#: The companion computer on the FMU's TELEM2 (USART3, /dev/ttyS2): an FTDI USB-serial cable
#: (/dev/ttyUSB0 on the companion) crossed TX to RX. Both ends start at their defaults (the
#: FMU's 57600, the cable's 921600) and the uORB bridge sets each to 921600 (the FMU's
#: SER_TEL2_BAUD); until then a byte sent at the wrong rate arrives as framing errors, as on
#: the wire. The companion's "ros" port is wired by hil.ros.link.add_ros_link.
COMPANION_WIRES: Final[list[Wire]] = uart_link(
    ("fmu", "telem2"), (COMPANION, "telem2"),
    "FMU TELEM2 (USART3) <-> companion /dev/ttyUSB0 (FTDI cable), 921600 8N1 (uORB bridge)")
