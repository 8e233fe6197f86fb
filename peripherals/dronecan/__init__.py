"""DroneCAN nodes on the FMU's CAN bus (GNSS, magnetometer), built on the ``dronecan`` package's
DSDL types through the shared transport in :mod:`firmware.lib.uavcan`."""
