"""A booted FMU with a UDP MAVLink link and a virtual-time ground station on it."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from hil.devices import DeviceHub
from hil.gcs import GcsClient, udp_wires
from hil.orchestrator import BoardSpec, Orchestrator

MS = 1_000_000
BOARD = "tests.mavlink.boards:MavlinkFmuBoard"
UDP_PORT = 18570


@dataclass
class Session:
    orch: Orchestrator
    gcs: GcsClient
    root: Path

    def shell(self, line: str) -> str:
        status, out = self.orch.call("fmu", "shell", line)
        assert status == 0, f"{line!r} failed: {out}"
        return out

    def counters(self, port: Any = UDP_PORT) -> dict:
        return next(d for d in self.orch.call("fmu", "mavlink", "counters") if d["port"] == port)

    def topic(self, name: str, instance: int = 0) -> dict | None:
        return self.orch.call("fmu", "topic", name, instance)

    def close(self) -> None:
        self.orch.close()

    def udp_instance(self) -> Any:
        """The FMU's MAVLink instance on the GCS's UDP link (in-process: tests read its
        counters and may patch its services)."""
        mod = self.orch.handles["fmu"].endpoint.board.system.modules.get("mavlink")
        return next(i for i in mod.instances if getattr(i.transport, "kind", "") == "udp")

    def dmesg_mark(self) -> int:
        """The FMU's virtual time in µs: :meth:`mavlink_errors` after it."""
        return int(self.orch.handles["fmu"].endpoint.board.platform.time_us())

    def mavlink_errors(self, since_us: int) -> list[str]:
        """The ``mavlink`` ERR (or worse) lines logged in dmesg since ``since_us``."""
        dmesg = self.orch.handles["fmu"].endpoint.board.platform.dmesg
        return [text for t_us, severity, module, text in dmesg
                if t_us >= since_us and severity <= 3 and module == "mavlink"]


def open_session(root: Path, gcs: GcsClient | None = None, start_udp: bool = True,
                 **board: Any) -> Session:
    (root / "sd").mkdir(parents=True, exist_ok=True)
    gcs = gcs or GcsClient("gcs", fmu_port=UDP_PORT)
    kwargs = {"fram_path": str(root / "fram.bin"), "sd_root": str(root / "sd")} | board
    orch = Orchestrator({"fmu": BoardSpec(BOARD, kwargs)}, udp_wires("gcs"),
                        world=DeviceHub(gcs), mode="local")
    orch.start()
    gcs.attach(orch)
    orch.run(duration_ns=350 * MS)  # boot: parameters from FRAM, rcS (mavlink on TELEM1)
    s = Session(orch, gcs, root)
    # rcS starts the GCS link on UDP_PORT itself (as PX4 SITL does); start it only if not.
    if start_udp and not any(d.get("port") == UDP_PORT
                             for d in orch.call("fmu", "mavlink", "counters")):
        s.shell(f"mavlink start -u {UDP_PORT} -o 14550")
    return s


def open_commander_session(root: Path) -> Session:
    """A booted FMU on the GCS link with the commander running (modes, arming, commands)."""
    s = open_session(root)
    s.gcs.wait_heartbeat()
    s.shell("commander start")
    s.gcs.step(0.3)
    return s


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    s = open_session(tmp_path_factory.mktemp("fmu"))
    s.gcs.wait_heartbeat()
    yield s
    s.close()


@pytest.fixture(autouse=True)
def _board_alive(request):
    """A firmware exception kills the board; say so instead of timing out later."""
    yield
    if "session" in request.fixturenames:
        s = request.getfixturevalue("session")
        assert not s.orch.dead, f"the FMU died: {s.orch.dead}"
