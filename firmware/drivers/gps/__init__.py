"""GPS drivers: the u-blox UBX driver (``GpsDriver``) and its protocol helpers (``ubx``)."""

from firmware.drivers.gps.gps import GpsDriver

__all__ = ["GpsDriver"]
