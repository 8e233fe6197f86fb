"""The DroneCAN transport both ends of the emulated CAN bus use: CAN IDs, transfers (framing,
CRC, toggle, reassembly with counted errors) and a transmit queue, on the ``dronecan``
package's DSDL serialisation (what libuavcan/libcanard are to PX4 and to node firmware)."""
