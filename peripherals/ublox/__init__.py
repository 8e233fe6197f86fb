"""u-blox M8 GNSS receiver model (UBX + NMEA on a UART).

``UbloxM8`` is the device; the solution model, configuration store, framing and message
encoders live in the submodules so each stays small and testable on its own.
"""

from peripherals.ublox.receiver import UbloxM8
from peripherals.ublox.solution import GnssErrorParams, GnssFaults

__all__ = ["GnssErrorParams", "GnssFaults", "UbloxM8"]
