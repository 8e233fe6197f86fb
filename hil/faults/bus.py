"""Bus and wire faults: what goes wrong on the copper between chips and between boards.

Wires between boards are faulted at the orchestrator's routing (the wire carries nothing, as a
broken conductor does); noise on a UART line is injected at the receiving USART inside the
board (each bit of each frame can flip, so the receiver sets PE/FE as an STM32 does); SPI, I2C
and CAN faults act on the board's bus models. A kind on a board's bus is one control hook
given the fault's arguments at its start and the healthy ones at its stop (:func:`_hook_kind`);
the wire cuts are the orchestrator's (:func:`hil.faults._rig.orchestrator`).
"""

from __future__ import annotations

from typing import Any

from collections.abc import Callable

from hil.faults import FaultError, Rig, switch_kind
from hil.faults._rig import board_call, number, orchestrator

FMU_IO_DIRECTIONS = ("both", "fmu_to_io", "io_to_fmu")
#: the FMU-IO serial link's two conductors, as the orchestrator routes them
_FMU_IO_WIRES = {"fmu_to_io": ("fmu", "io_link"), "io_to_fmu": ("io", "fmu_link")}


def _split(target: str, fault: str, what: str) -> tuple[str, str]:
    board, dot, rest = target.partition(".")
    if not dot or not board or not rest:
        raise FaultError(f"fault {fault}: target must be 'board.{what}', got {target!r}")
    return board, rest


def _hook_kind(name: str, method: str, what: str, doc: str,
               on: Callable[[dict[str, Any]], tuple], off: tuple,
               targets: tuple[str, ...] = (), **params: Any) -> None:
    """A kind on target ``'board.<what>'``: the board's ``ctl_<method>(<what>, *on(params))``
    at its start, ``ctl_<method>(<what>, *off)`` at its stop."""

    def apply(rig: Rig, target: str, p: dict[str, Any], active: bool) -> tuple[str, str]:
        board, part = _split(target, name, what)
        board_call(rig, name, board, method, part, *(on(p) if active else off))
        return (board, part)

    switch_kind(name, apply, level="bus", doc=doc, targets=targets, **params)


def _fmu_io_link_cut(rig: Rig, target: str, params: dict[str, Any], on: bool) -> list[str]:
    orch = orchestrator(rig, "bus.fmu_io_link_cut")
    wires = list(_FMU_IO_WIRES) if target == "both" else [target]
    for w in wires:
        (orch.cut_wire if on else orch.mend_wire)(*_FMU_IO_WIRES[w])
    return wires


switch_kind("bus.fmu_io_link_cut", _fmu_io_link_cut, level="bus", targets=FMU_IO_DIRECTIONS,
            doc="A conductor of the FMU-IO serial link (FMU USART6 <-> IO USART2) breaks: the "
                "wire carries nothing, in one direction or both. Cutting fmu_to_io stops the "
                "CONTROLS writes: 500 ms later the IO declares the FMU lost, raises "
                "ALARM_FMU_LOST and drives its failsafe PWM (or the RC override when allowed). "
                "Either direction leaves the FMU's px4io driver without replies: each transaction "
                "times out after 10 ms x 3 tries, and after 10 failed calls in a row (~0.3 s) it "
                "logs 'IO lost' and counts link errors in px4io_status.")


def _wire_cut(rig: Rig, target: str, params: dict[str, Any], on: bool) -> tuple[str, str]:
    board, port = _split(target, "bus.wire_cut", "port")
    orch = orchestrator(rig, "bus.wire_cut")
    if not on:
        orch.mend_wire(board, port)
        return (board, port)
    try:
        orch.cut_wire(board, port)
    except ValueError as exc:
        raise FaultError(f"fault bus.wire_cut: {exc}") from None
    return (board, port)


switch_kind("bus.wire_cut", _wire_cut, level="bus",
            doc="Any wire leaving a board or the world breaks (target 'board.port', e.g. "
                "'io.pwm1' for the signal wire of ESC 1, 'world.rc_sbus' for the receiver cable): "
                "the far end sees an open line: a UART receives nothing, an ESC sees no pulses "
                "(it holds its throttle 0.5 s, then stops the motor and disarms), a pin input "
                "floats to its pull. Mending restores the present level.")


def _uart_noise(p: dict[str, Any]) -> tuple:
    name = "bus.uart_noise"
    ber = number(p, "bit_error_rate", name, 0.0, 1.0)
    drop = number(p, "drop_rate", name, 0.0, 1.0)
    if not ber and not drop:
        raise FaultError(f"fault {name}: give a bit_error_rate or a drop_rate above 0")
    return (ber, drop)


_hook_kind("bus.uart_noise", "uart_fault", "UART",
           "Noise on a UART's receive line (target 'board.UART', e.g. 'io.USART2' for what the IO "
           "hears from the FMU, 'fmu.USART6' for the replies, 'fmu.UART4' for the GPS): each bit "
           "of each frame flips with bit_error_rate (a data bit corrupts the byte, a parity bit "
           "or an odd number of flips sets PE, the stop bit sets FE, a start bit loses the frame) "
           "and whole bytes are lost with drop_rate; seeded by the board's seed. The PX4IO "
           "protocol's CRC8 rejects corrupt packets (the IO answers CORRUPT, the FMU retries and "
           "counts link errors); the GPS driver drops frames with bad checksums.",
           _uart_noise, (0.0, 0.0), bit_error_rate=1e-4, drop_rate=0.0)
_hook_kind("bus.spi_miso_stuck", "spi_miso_stuck", "SPIn",
           "An SPI bus's MISO line is stuck (target 'board.SPIn', e.g. 'fmu.SPI1' with the "
           "MPU6000, L3GD20, LSM303D and MS5611): level_high=1 reads 0xFF from every device (a "
           "cracked trace floating to the pull-up, a chip that no longer drives), 0 reads 0x00 (a "
           "short to ground). The devices still receive MOSI. Each driver sees impossible "
           "registers (WHO_AM_I 0xFF, an all-ones FIFO count), counts bad transfers in "
           "error_count and resets its chip, retrying until the bus heals; the sensors module's "
           "voter drops the silent sensors.",
           lambda p: (int(number(p, "level_high", "bus.spi_miso_stuck", 0, 1)),), (None,),
           level_high=1)


def _nak_rate(p: dict[str, Any]) -> tuple:
    rate = number(p, "nak_rate", "bus.i2c_nak_storm", 0.0, 1.0)
    if rate == 0:
        raise FaultError("fault bus.i2c_nak_storm: nak_rate must be above 0")
    return (rate, False)


_hook_kind("bus.i2c_nak_storm", "i2c_fault", "I2Cn",
           "A fraction nak_rate of the transactions on an I2C bus (target 'board.I2Cn', e.g. "
           "'fmu.I2C1' with the GPS module's HMC5883L) is not acknowledged: a marginal pull-up, "
           "EMI on the GPS cable, a device browning out. The driver gets -EIO, counts a bad "
           "transfer and retries at its next cycle; with 1.0 the magnetometer goes silent and the "
           "sensors module's voter fails over.",
           _nak_rate, (0.0, False), nak_rate=1.0)
_hook_kind("bus.i2c_sda_stuck", "i2c_fault", "I2Cn",
           "SDA of an I2C bus is held low (a device reset in the middle of a byte keeps driving "
           "it; a short): the controller cannot make a START, so every transaction fails with "
           "-ETIMEDOUT after a 1 ms wait for the bus, until the fault is cleared. Every driver on "
           "that bus stops publishing and counts errors.",
           lambda p: (0.0, True), (0.0, False))


def _can_wire(p: dict[str, Any]) -> tuple:
    name = "bus.can_bus_off"
    short = int(number(p, "short", name, 0, 1))
    ber = number(p, "bit_error_rate", name, 0.0, 1.0)
    if not short and not ber:
        raise FaultError(f"fault {name}: give short=1 or a bit_error_rate above 0")
    return (bool(short), ber)


_hook_kind("bus.can_bus_off", "can_fault", "CANn",
           "The FMU's CAN bus wire goes bad: CAN_H shorted to CAN_L (short=1, a crushed cable, a "
           "connector pin bent across) holds the bus recessive, so every transmitter reads back "
           "recessive at its dominant SOF (a bit error: TEC += 8, and nobody sees its error "
           "flag); or each bit is corrupted with bit_error_rate (EMI, a missing terminator), "
           "every node counting the error frame. After 32 failed attempts (TEC > 255, ~0.7 ms at "
           "1 Mbit/s with a short) the bxCAN goes bus-off; with ABOM it rejoins after 128 x 11 "
           "recessive bits (1.4 ms) and fails again while the fault lasts. PX4's uavcan driver "
           "counts bus-off events from the error interrupt and reports the controller state, TEC "
           "and REC (uavcan status, can_interface_status); the other nodes' NodeStatus stops "
           "arriving and they go offline 3 s after the last one. When the wire is mended the "
           "controller recovers and NodeStatus traffic resumes.",
           _can_wire, (False, 0.0), targets=("fmu.CAN1", "fmu.CAN2"), short=1,
           bit_error_rate=0.0)
_hook_kind("bus.can_node_silent", "can_node_silent", "<CAN node>",
           "A DroneCAN node on the FMU's CAN1 goes silent (target 'fmu.<node>': its name, "
           "uavcan_node125, can_gnss, can_mag, or its node ID): its MCU hangs or its stub cable "
           "is cut, so it sends nothing and no longer ACKs; the rest of the bus carries on. Its "
           "NodeStatus stops, and with it anything it published (a CAN GNSS's Fix2, a compass's "
           "field). PX4's uavcan driver marks a node offline 3 s after its last NodeStatus (the "
           "DroneCAN offline timeout): can_interface_status.nodes_online drops, `uavcan status` "
           "lists it offline and dmesg says so; when it talks again it is back online.",
           lambda p: (True,), (False,))


def _esc_error_rate(p: dict[str, Any]) -> tuple:
    rate = number(p, "errors_per_s", "bus.can_esc_errors", 0.0, 10_000.0)
    if rate == 0:
        raise FaultError("fault bus.can_esc_errors: errors_per_s must be above 0")
    return (rate,)


_hook_kind("bus.can_esc_errors", "can_esc_errors", "<CAN ESC node>",
           "A DroneCAN ESC on the FMU's CAN1 fails (target 'fmu.<node>': its name, can_esc2@12, "
           "or its node ID, 12): a desyncing motor, a bad phase or a browning-out supply makes "
           "its firmware count errors_per_s errors, which its esc.Status reports in error_count, "
           "and its NodeStatus health goes to WARNING; it keeps driving its motor. The FMU's "
           "uavcan driver shows the count in esc_status.esc[i].esc_errorcount and `uavcan status` "
           "(errors N), the node's health in its node table. The count stays when the fault "
           "clears, as an ESC's counter does until it restarts. A dead ESC is bus.can_node_silent "
           "on it: it stops its motor and the commander reports 'ESCn offline'.",
           _esc_error_rate, (0.0,), errors_per_s=10.0)
