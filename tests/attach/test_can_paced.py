"""Paced (``hil fly``'s mode): the plug-in over TCP gets the FMU's frames with wall-clock
timestamps, and its own frame comes back confirmed with the wall time it went out."""

from __future__ import annotations

import threading
import time

import can
import pytest

from hil.can_interface_host import find_host
from hil.system import SystemConfig, build_system

from .conftest import FMU_NODE_STATUS_ID

NS_PER_S = 1_000_000_000


@pytest.mark.paced
def test_paced_frames_carry_wall_clock_timestamps(tmp_path):
    orch, _dev = build_system(SystemConfig(
        seed=1, out_dir=str(tmp_path), mode="local", rc=None, speed=1.0, can_hosts=("CAN1",),
        can_tcp=True, params={"UAVCAN_ENABLE": 1}))
    host, _ = find_host(orch, "CAN1")
    with orch:
        bus = can.Bus(interface="hil", channel="CAN1", port=host.tcp_port,
                      receive_own_messages=True)
        runner = threading.Thread(target=orch.run, kwargs={"duration_ns": 3 * NS_PER_S})
        runner.start()
        try:
            got = None
            deadline = time.monotonic() + 10
            while got is None and time.monotonic() < deadline:
                m = bus.recv(1.0)
                if m is not None and m.arbitration_id == FMU_NODE_STATUS_ID:
                    got, now = m, time.time()
            assert got is not None, "no NodeStatus within 10 s"
            assert got.is_rx and abs(got.timestamp - now) < 0.25, (got.timestamp, now)
            sent_at = time.time()
            bus.send(can.Message(arbitration_id=0x42, is_extended_id=False, data=b"hi"))
            echo = None
            while echo is None and time.monotonic() < deadline:
                m = bus.recv(1.0)
                if m is not None and not m.is_rx:
                    echo = m
            assert echo is not None and echo.arbitration_id == 0x42 and echo.data == b"hi"
            assert -0.05 < echo.timestamp - sent_at < 0.3, (echo.timestamp, sent_at)
        finally:
            runner.join(30)
            bus.shutdown()
            host.close()
