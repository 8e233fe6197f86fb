"""A ``dronecan`` node in this process (through python-can's ``hil`` plug-in, on the shared
rig of tests/attach) asks the FMU for GetNodeInfo and gets the uavcan driver's answer: the
package's own Node, request/response matching and transfer CRC, against our driver."""

from __future__ import annotations

import dronecan

from .conftest import FMU_NODE_ID


def test_dronecan_node_gets_the_fmu_node_info(can_rig):
    node = dronecan.make_node("CAN1", bustype="hil", bitrate=1000000, node_id=101)
    answers = []
    try:
        node.request(dronecan.uavcan.protocol.GetNodeInfo.Request(), FMU_NODE_ID,
                     lambda e: answers.append(e), timeout=30)
        end = can_rig.orch.t_ns + 2_000_000_000
        while can_rig.orch.t_ns < end and not answers:
            node.spin(0.001)
    finally:
        node.close()
    assert answers and answers[0] is not None, "no GetNodeInfo response from the FMU"
    r = answers[0].response
    assert answers[0].transfer.source_node_id == FMU_NODE_ID
    assert r.name.decode() == "org.pixhawk.fmuv2"
    assert (r.software_version.major, r.software_version.minor) == (1, 14)
    assert abs(r.status.uptime_sec - can_rig.orch.t_ns / 1e9) <= 1.5  # the FMU's uptime
    assert len(r.hardware_version.unique_id) == 16
