"""One emulated Pixhawk (in this process, unpaced) with tools attached to the FMU's CAN1.

The system is shared by the package's tests (building and booting it is most of their cost):
UAVCAN_ENABLE=1 so the FMU's uavcan driver sends NodeStatus (node 1) once a second, CAN1 has
its host side with a TCP endpoint (tools in other processes) and a binding to python-can's
``virtual`` bus ``VIRTUAL_CHANNEL`` (``hil fly --can CAN1=virtual:...``); TELEM1 is on its host
pty and TCP port (``hil://TELEM1``) and TELEM2 is bound to the slave end of a pty pair whose
master the tests hold (``hil fly --uart telem2=/dev/pts/N``). The tests drive the orchestrator
themselves, in virtual time.
"""

from __future__ import annotations

import os
import time
from typing import Any, Callable

import pytest

from hil.can_interface_host import CanHost, find_host, register, unregister
from hil.system import SystemConfig, build_system

NS_PER_S = 1_000_000_000
VIRTUAL_CHANNEL = "hil_attach_tests"
FMU_NODE_ID = 1
#: uavcan.protocol.NodeStatus from the FMU's node 1 (priority 16, data type 341)
FMU_NODE_STATUS_ID = (16 << 24) | (341 << 8) | FMU_NODE_ID


class CanRig:
    def __init__(self, orch: Any, dev: dict[str, Any], host: CanHost, log: list[str],
                 telem2_master: int) -> None:
        self.telem2_master = telem2_master
        self.orch = orch
        self.dev = dev
        self.host = host
        self.log = log

    def run_s(self, seconds: float) -> None:
        self.orch.run(duration_ns=int(seconds * NS_PER_S))

    def run_until(self, pred: Callable[[], Any], wall_s: float, what: str,
                  step_s: float = 0.05, max_virtual_s: float = 30.0) -> Any:
        """Drive the emulator in small steps until ``pred()`` (bounded in wall and virtual
        time: a tool in another process needs wall time to start)."""
        deadline = time.monotonic() + wall_s
        end = self.orch.t_ns + int(max_virtual_s * NS_PER_S)
        while True:
            v = pred()
            if v:
                return v
            if time.monotonic() > deadline or self.orch.t_ns > end:
                raise AssertionError(f"timed out waiting for {what}")
            self.run_s(step_s)
            time.sleep(0.001)  # let a tool in another process run on a busy machine

    def uavcan(self) -> dict[str, Any]:
        st = self.orch.call("fmu", "topic", "can_interface_status")
        assert st is not None, "the FMU's uavcan driver published nothing"
        return st

    def uavcan_status(self) -> str:
        return self.orch.call("fmu", "shell", "uavcan status")[1]


@pytest.fixture(scope="package")
def can_rig(tmp_path_factory: pytest.TempPathFactory):
    log: list[str] = []
    master, slave = os.openpty()
    slave_path = os.ttyname(slave)
    os.close(slave)  # the binding opens it by name, as a user's device
    os.set_blocking(master, False)
    orch, dev = build_system(SystemConfig(
        seed=1, out_dir=str(tmp_path_factory.mktemp("can_rig")), mode="local", rc=None,
        can_hosts=("CAN1",), can_tcp=True, can_bind={"CAN1": f"virtual:{VIRTUAL_CHANNEL}"},
        telem_pty=True, uart_tcp=True, uart_bind={"telem2": slave_path},
        params={"UAVCAN_ENABLE": 1}))
    host, _ = find_host(orch, "CAN1")
    host.log = log.append
    dev["uart_bindings"]["telem2"].log = log.append
    with orch:
        register(host, orch)
        rig = CanRig(orch, dev, host, log, master)
        rig.run_s(0.5)  # boot: the uavcan driver starts at ~0.32 s
        try:
            yield rig
        finally:
            unregister(host)
            host.close()
            dev["telem1"].close()
            dev["uart_bindings"]["telem2"].close()
            if rig.telem2_master >= 0:
                os.close(rig.telem2_master)
