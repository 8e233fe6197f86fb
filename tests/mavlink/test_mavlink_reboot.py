"""PREFLIGHT_REBOOT_SHUTDOWN reboots the FMU in the run: a new board process boots from its own
time zero on the same FRAM, so a parameter set before the reboot is still there."""

from hil.devices import DeviceHub
from hil.gcs import GcsClient, udp_wires
from hil.orchestrator import BoardSpec, Orchestrator

MS = 1_000_000
S = 1_000_000_000


def test_reboot_keeps_parameters(tmp_path):
    (tmp_path / "sd").mkdir()
    gcs = GcsClient("gcs", fmu_port=18570)
    kwargs = {"fram_path": str(tmp_path / "fram.bin"), "sd_root": str(tmp_path / "sd"),
              "params": {"SYS_AUTOSTART": 4011}}  # a vehicle: the commander handles reboot
    log: list[str] = []
    orch = Orchestrator({"fmu": BoardSpec("fmu.board:FmuV2Board", kwargs)}, udp_wires("gcs"),
                        world=DeviceHub(gcs), mode="process", log=log.append)
    with orch:
        gcs.attach(orch)
        gcs.wait_heartbeat(timeout_s=5)
        assert gcs.param_set("SDLOG_PROFILE", 9) == 9
        orch.run(duration_ns=1 * S)  # the autosave (300 ms) reaches FRAM
        ack = gcs.command_long(246, (1,))  # MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN: reboot autopilot
        assert ack.result == 0
        t_reboot = orch.t_ns
        orch.run(duration_ns=150 * MS)
        assert orch.reboots.get("fmu") == 1
        assert any("rebooted" in line for line in log)
        mark = gcs.mark()
        gcs.wait_message("HEARTBEAT", timeout_s=10, since=mark)  # from the new board
        assert gcs.param_get("SDLOG_PROFILE") == 9
        # The new board counts its time from the reboot, as a real FMU's clock does.
        status = orch.call("fmu", "topic", "vehicle_status")
        assert status is None or status["timestamp"] < (orch.t_ns - t_reboot) // 1000 + 1000
