"""The FMU board the MAVLink tests run: the stock FmuV2Board (it has the UDP ports, the
multi-link ``mavlink start`` and ``ctl_mavlink``)."""

from fmu.board import FmuV2Board as MavlinkFmuBoard

__all__ = ["MavlinkFmuBoard"]
