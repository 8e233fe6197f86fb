"""``hil fly --can CAN1=virtual:<channel>``: the emulated CAN1 joined to python-can's ``virtual``
bus, frames both ways; a bus that closes under it is reported and the emulator keeps going.

Driven unpaced from virtual time (the rig's orchestrator); the binding polls the real side
between quanta, as it does in ``hil fly``.
"""

from __future__ import annotations

import re

import can
import dronecan
import pytest
from dronecan.transport import Transfer

from hil.bindings_can import BoundBus, parse_can_spec
from hil.bindings_uart import UartBinding
from hil.fly import main as fly_main

from .conftest import FMU_NODE_STATUS_ID, VIRTUAL_CHANNEL


def _node_status(node_id: int, uptime_s: int, tid: int) -> can.Message:
    (frame,) = Transfer(payload=dronecan.uavcan.protocol.NodeStatus(uptime_sec=uptime_s),
                        source_node_id=node_id, transfer_id=tid, transfer_priority=16,
                        service_not_message=False).to_frames()
    return can.Message(arbitration_id=frame.message_id, is_extended_id=True,
                       data=bytes(frame.bytes))


def test_virtual_bus_carries_frames_both_ways(can_rig):
    peer = can.Bus(interface="virtual", channel=VIRTUAL_CHANNEL)
    try:
        can_rig.run_s(1.2)
        got = []
        while (m := peer.recv(0)) is not None:
            got.append(m)
        assert any(m.arbitration_id == FMU_NODE_STATUS_ID for m in got), got
        for i in range(2):
            peer.send(_node_status(55, 40 + i, i))
        can_rig.run_s(0.1)
        status = can_rig.uavcan_status()
        assert re.search(r"node 55: online, .*uptime 41 s", status), status
        binding = can_rig.dev["can1_bind"]
        assert binding.frames_in >= 2 and binding.frames_out >= 1
        # frames relayed from the virtual bus are not echoed back to it
        echoed = []
        while (m := peer.recv(0)) is not None:
            echoed.append(m)
        assert not any((m.arbitration_id & 0x7F) == 55 for m in echoed), echoed
    finally:
        peer.shutdown()


def test_closed_bus_is_reported_and_the_emulator_keeps_running(can_rig):
    host = can_rig.host
    bad = BoundBus("virtual:hil_attach_closing", host.bitrate, log=can_rig.log.append)
    host.attach(bad)
    can_rig.run_s(0.1)
    bad.bus.shutdown()  # the adapter goes away under the binding
    rx_before = can_rig.uavcan()["frames_tx"]
    can_rig.run_s(1.2)
    assert bad.closed and bad not in host.endpoints
    assert any("CAN binding virtual:hil_attach_closing failed" in line for line in can_rig.log), \
        can_rig.log
    assert can_rig.uavcan()["frames_tx"] > rx_before, "the FMU stopped sending"
    assert not can_rig.orch.dead


def test_fly_rejects_bad_can_and_uart_specs(capsys):
    assert fly_main(can=["CAN1"], duration_s=0) == 2
    assert "NAME=VALUE" in capsys.readouterr().err
    assert fly_main(can=["CAN3=virtual:x"], duration_s=0) == 2
    assert "no CAN bus 'CAN3'" in capsys.readouterr().err
    assert fly_main(can=["CAN1=vcan0"], duration_s=0) == 2
    assert "<interface>:<channel>" in capsys.readouterr().err
    assert parse_can_spec("slcan:/dev/ttyACM0@115200") == ("slcan", "/dev/ttyACM0@115200")
    assert fly_main(uart=["serial5=/dev/ttyUSB0"], duration_s=0) == 2
    assert "no connector 'serial5'" in capsys.readouterr().err
    with pytest.raises(ValueError, match="--uart gps=/dev/hil-no-such-device: cannot open"):
        UartBinding("gps", "/dev/hil-no-such-device", "uart_gps", (9600, 8, "N", 1, 0), 500_000)
