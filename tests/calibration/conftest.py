"""A lone FMU on a calibration jig, with a pymavlink ground station in virtual time.

One board for the whole package (it is cheap: ~0.2 s of CPU per virtual second): the jig
(hil/calibration_jig.py) owns the board's ``truth`` port and holds the vehicle level unless a
test turns or shakes it; the GCS reaches the FMU's UDP MAVLink port as QGroundControl does.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as mav

from hil.calibration_jig import TRUTH_WIRE, CalibrationJig, statustexts
from hil.devices import DeviceHub
from hil.gcs import GcsClient, udp_wires
from hil.orchestrator import BoardSpec, Orchestrator

MS = 1_000_000
BOARD = "tests.mavlink.boards:MavlinkFmuBoard"
CAL = mav.MAV_CMD_PREFLIGHT_CALIBRATION
#: the texts that end a calibration in QGroundControl's parser
ENDINGS = ("[cal] calibration done", "[cal] calibration failed", "[cal] calibration cancelled")


@dataclass
class Rig:
    orch: Orchestrator
    gcs: GcsClient
    jig: CalibrationJig

    @property
    def board(self) -> Any:
        return self.orch.handles["fmu"].endpoint.board

    @property
    def params(self) -> Any:
        return self.board.system.params

    def texts(self, since: int) -> list[str]:
        return statustexts(self.gcs.messages("STATUSTEXT", since))

    def cal_texts(self, since: int) -> list[str]:
        return [t for t in self.texts(since) if t.startswith("[cal]")]

    def run_until_end(self, since: int, timeout_s: float) -> list[str]:
        """Run until a calibration-ending STATUSTEXT; the [cal] texts since ``since``."""
        t = 0.0
        while not any(x.startswith(ENDINGS) for x in self.texts(since)):
            assert t < timeout_s, f"no end of calibration in {timeout_s} s: {self.texts(since)}"
            self.gcs.step(0.05)
            t += 0.05
        return self.cal_texts(since)

    def calibrate(self, *params: float) -> Any:
        return self.gcs.command_long(CAL, list(params) + [0.0] * (7 - len(params)))

    def sensor(self, topic: str, instance: int) -> dict:
        m = self.orch.call("fmu", "topic", topic, instance)
        assert m is not None, f"no {topic}[{instance}]"
        return m


@pytest.fixture(scope="package")
def rig(tmp_path_factory):
    root: Path = tmp_path_factory.mktemp("calibration")
    (root / "sd").mkdir()
    gcs = GcsClient("gcs", fmu_port=18570)
    jig = CalibrationJig()
    orch = Orchestrator({"fmu": BoardSpec(BOARD, {"fram_path": str(root / "fram.bin"),
                                                  "sd_root": str(root / "sd")})},
                        udp_wires("gcs") + [TRUTH_WIRE], world=DeviceHub(gcs, jig),
                        mode="local")
    orch.start()
    try:
        gcs.attach(orch)
        orch.run(duration_ns=350 * MS)
        gcs.wait_heartbeat()
        status, out = orch.call("fmu", "shell", "commander start")
        assert status == 0, out
        gcs.step(0.3)
        yield Rig(orch, gcs, jig)
    finally:
        orch.close()


@pytest.fixture(autouse=True)
def _board_alive(request):
    yield
    if "rig" in request.fixturenames:
        r = request.getfixturevalue("rig")
        assert not r.orch.dead, f"the FMU died: {r.orch.dead}"
