"""CAN bus-off from a faulty wire: the FMU's bxCAN on CAN1, a UAVCAN node beside it, the uavcan
driver's report (can_interface_status, ``uavcan status``) and the catalogue kind's hook."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from fmu.board import FmuV2Board
from hil.faults import FaultError, get_kind

S = 1_000_000_000
MS = 1_000_000


def _board(tmp_path, enable=1, nodes=(125,)):
    return FmuV2Board(seed=2, fram_path=str(tmp_path / "fram.bin"), sd_root=str(tmp_path),
                      params={"SYS_AUTOSTART": 0, "UAVCAN_ENABLE": enable}, uavcan_nodes=nodes)


def _rig(board):
    orch = SimpleNamespace(handles={"fmu": None}, t_ns=0,
                           call=lambda name, method, *args: board.call(method, *args))
    return SimpleNamespace(orch=orch, dev={})


def _status(board):
    return board.ctl_topic("can_interface_status")


def test_default_build_has_no_can_traffic_and_no_can_hardware(tmp_path):
    b = _board(tmp_path, enable=0, nodes=())
    b.kernel.run(2 * S)
    assert "uavcan" not in b.system.modules.running()
    assert b._can is None  # never built: python-can not even imported for it
    assert _status(b) is None


def test_uavcan_disabled_leaves_the_fmu_controller_asleep(tmp_path):
    b = _board(tmp_path, enable=0)
    b.kernel.run(2_500 * MS)
    st = b.ctl_can_stats("CAN1")
    assert not st["enabled"] and st["rx_frames"] == 0
    node = st["nodes"][125]
    assert node["node_status_tx"] == 0 and node["tx_timeouts"] >= 1  # nobody ACKs it


def test_short_bus_off_within_32_attempts_reported_then_recovery(tmp_path):
    b = _board(tmp_path)
    k = b.kernel
    k.run(3_200 * MS)
    st = _status(b)
    assert st["state"] == 0 and st["nodes_online"] == 1 and st["node_status_rx"] >= 2
    assert b.ctl_can_stats("CAN1")["nodes"][125]["heard"][1] >= 2  # the peer hears the FMU
    ok, out = b.ctl_shell("uavcan status")
    assert ok == 0 and "CAN1: error-active, TEC 0 REC 0, bus-off 0" in out
    assert "node 125: online" in out

    rig, kind = _rig(b), get_kind("bus.can_bus_off")
    params = kind.check("fmu.CAN1", {})
    token = kind.start(rig, "fmu.CAN1", params, k.now_ns)
    t_fault = k.now_ns
    # the FMU's next NodeStatus is its first attempt: 32 errors later it is bus-off (spec:
    # 16 x 18 bits, then 16 x (8 + 18) with the error-passive suspend; <= 0.75 ms at 1 Mbit/s)
    ctrl = b.can_ctrl["CAN1"]
    while ctrl.bus_off_count == 0:
        k.run(k.now_ns + 10_000)
        assert k.now_ns - t_fault < 1_100 * MS
    first_err = ctrl.tx_errors
    assert first_err == 32
    k.run(k.now_ns + 150 * MS)
    st = _status(b)
    assert st["bus_off_count"] >= 1 and st["last_bus_off"] * 1000 > t_fault
    rx_before = st["node_status_rx"]
    k.run(t_fault + 3_200 * MS)
    st = _status(b)
    assert st["node_status_rx"] == rx_before and st["nodes_online"] == 0
    assert st["tx_timeouts"] >= 2 and st["bus_off_count"] > 100
    _, out = b.ctl_shell("uavcan status")
    assert "node 125: offline" in out

    kind.stop(rig, "fmu.CAN1", params, k.now_ns, token)
    t_heal = k.now_ns
    k.run(t_heal + 300 * MS)
    st = _status(b)
    assert st["state"] != 2 and st["nodes_online"] == 1 and st["node_status_rx"] > rx_before
    assert st["recoveries"] >= 1
    k.run(t_heal + 1_500 * MS)
    assert ctrl.state != "bus_off" and b.ctl_can_stats("CAN1")["nodes"][125]["heard"][1] > 3


def test_bit_error_rate_variant_and_bad_parameters(tmp_path):
    b = _board(tmp_path)
    b.kernel.run(2_200 * MS)
    rig, kind = _rig(b), get_kind("bus.can_bus_off")
    token = kind.start(rig, "fmu.CAN1", kind.check("fmu.CAN1", {"short": 0,
                                                               "bit_error_rate": 0.05}), 0)
    b.kernel.run(4_500 * MS)
    assert _status(b)["bus_off_count"] >= 1
    assert b.ctl_can_stats("CAN1")["wire_fault"] == (False, 0.05)
    kind.stop(rig, "fmu.CAN1", {}, 0, token)
    assert b.ctl_can_stats("CAN1")["wire_fault"] == (False, 0.0)
    with pytest.raises(FaultError, match="short=1 or a bit_error_rate"):
        kind.start(rig, "fmu.CAN1", kind.check("fmu.CAN1", {"short": 0}), 0)
    with pytest.raises(FaultError, match="outside"):
        kind.start(rig, "fmu.CAN1", kind.check("fmu.CAN1", {"bit_error_rate": 2}), 0)
    with pytest.raises(FaultError, match="not one of"):
        kind.check("fmu.CAN3", {})
