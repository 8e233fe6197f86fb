"""The PX4IO E14 firmware as it runs on the emulated IOv2 chip.

``main`` boots it and runs the main loop; ``serial_link`` answers the FMU from the USART2 IDLE
interrupt; ``mixer_tick`` decides the output source, arming and the pulses; ``controls`` turns
RC bytes and PPM captures into the RC pages, RC loss and override; ``safety`` debounces the
safety button and drives the LEDs; ``pwm_out`` and ``sbus_out`` are the output drivers.
"""

import zlib

from ioproc.firmware.hardware import IoHardware
from ioproc.firmware.main import LOOP_PERIOD_NS, IoFirmware
from ioproc.firmware.mixer_tick import FMU_INPUT_DROP_LIMIT_US, MixSource

__all__ = [
    "FIRMWARE_CRC",
    "FMU_INPUT_DROP_LIMIT_US",
    "IMAGE_SIZE",
    "LOOP_PERIOD_NS",
    "IoFirmware",
    "IoHardware",
    "MixSource",
    "firmware_crc32",
    "firmware_image",
]

#: Application flash the IO bootloader checks: 0xF000 bytes from 0x08001000 (§3.11).
IMAGE_SIZE = 0xF000


def firmware_crc32(data: bytes, crc: int = 0) -> int:
    """NuttX ``crc32part``: reflected poly 0xEDB88320, caller's init, no final XOR.

    zlib's CRC-32 inverts before and after; undoing both gives the raw table walk
    ("123456789" -> 0x2DFD2D88).
    """
    return zlib.crc32(data, crc ^ 0xFFFFFFFF) ^ 0xFFFFFFFF


def firmware_image() -> bytes:
    """[model] The 'flash contents' of this emulated IO: an identification string padded
    with erased flash (0xFF) to the application size, as the FMU pads its bundled image."""
    ident = b"fmu-hil px4io-v2 E14 (protocol 4)"
    return ident + b"\xff" * (IMAGE_SIZE - len(ident))


#: SETUP regs 11/12 of this IO: what an FMU bundling the same image computes.
FIRMWARE_CRC = firmware_crc32(firmware_image())
