"""HEARTBEAT as PX4 sends it, on UDP and on the TELEM1 UART that rcS starts; telemetry_status
tells the commander when the ground station was last heard."""

from pymavlink.dialects.v20 import common as mav

from board.wiring import WORLD, uart_link
from firmware.modules.mavlink.streams import base_mode_and_state, custom_mode
from hil.devices import DeviceHub
from hil.gcs import GcsClient
from hil.orchestrator import BoardSpec, Orchestrator
from tests.mavlink.conftest import BOARD


def test_heartbeat_px4_autopilot_quadrotor(session):
    hb = session.gcs.wait_heartbeat()
    assert hb.autopilot == mav.MAV_AUTOPILOT_PX4
    assert hb.type == mav.MAV_TYPE_QUADROTOR
    assert hb.base_mode & mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    assert not hb.base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED
    assert hb.get_srcSystem() == 1 and hb.get_srcComponent() == 1
    assert hb.get_header().incompat_flags == 0 and hb.get_msgbuf()[0] == 0xFD  # MAVLink 2


def test_heartbeat_type_follows_mav_type(session):
    """The airframe's MAV_TYPE is what ground stations see (a plane: MAV_TYPE_FIXED_WING)."""
    try:
        session.shell("param set MAV_TYPE 1")
        mark = session.gcs.mark()
        session.gcs.step(1.1)
        hbs = [m for m in session.gcs.messages("HEARTBEAT", mark) if m.get_srcSystem() == 1]
        assert hbs and hbs[-1].type == mav.MAV_TYPE_FIXED_WING
    finally:
        session.shell("param set MAV_TYPE 2")
    mark = session.gcs.mark()
    session.gcs.step(1.1)
    hbs = [m for m in session.gcs.messages("HEARTBEAT", mark) if m.get_srcSystem() == 1]
    assert hbs and hbs[-1].type == mav.MAV_TYPE_QUADROTOR


def test_heartbeats_at_1hz_of_virtual_time(session):
    gcs = session.gcs
    mark = gcs.mark()
    gcs.step(3.0)
    n = len([m for m in gcs.messages("HEARTBEAT", mark) if m.get_srcSystem() == 1])
    assert n in (3, 4)


def test_gcs_heartbeat_published_for_the_commander(session):
    session.gcs.step(1.1)
    t = session.topic("telemetry_status", 1)  # instance 1: the UDP link (TELEM1 is 0)
    assert t is not None and t["type"] == 2
    assert t["heartbeat_gcs_timestamp"] > 0 and t["heartbeat_type_gcs"]
    assert t["gcs_system_id"] == 255


def test_custom_mode_follows_nav_state():
    assert custom_mode(2) == 3 << 16                      # Position
    assert custom_mode(3) == (4 << 16) | (4 << 24)        # Auto Mission
    assert custom_mode(5) == (4 << 16) | (5 << 24)        # Auto RTL
    assert custom_mode(17) == (4 << 16) | (2 << 24)       # Auto Takeoff

    class Status:
        arming_state, nav_state, failsafe = 2, 3, False
    base, state = base_mode_and_state(Status, False)
    assert base & mav.MAV_MODE_FLAG_SAFETY_ARMED and base & mav.MAV_MODE_FLAG_AUTO_ENABLED
    assert state == mav.MAV_STATE_ACTIVE


def test_heartbeat_on_telem1_uart_from_rcs(tmp_path):
    (tmp_path / "sd").mkdir()
    gcs = GcsClient("telem1", link="uart", baud=57_600)
    orch = Orchestrator({"fmu": BoardSpec(BOARD, {"fram_path": str(tmp_path / "fram.bin"),
                                                  "sd_root": str(tmp_path / "sd")})},
                        uart_link(("fmu", "telem1"), (WORLD, "telem1")), world=DeviceHub(gcs),
                        mode="local")
    try:
        orch.start()
        gcs.attach(orch)
        hb = gcs.wait_heartbeat(timeout_s=2.0)
        assert hb.autopilot == mav.MAV_AUTOPILOT_PX4
        assert gcs.param_get("MAV_SYS_ID") == 1  # requests work at 57600 baud too
        status = orch.call("fmu", "shell", "mavlink status")[1]
        assert "serial /dev/ttyS1 @ 57600 baud" in status
    finally:
        orch.close()
