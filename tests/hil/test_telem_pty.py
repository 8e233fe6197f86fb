"""TELEM1 reaches the host as a pseudo-terminal: a ground station on the pty (pymavlink's
mavutil, as MAVProxy would use it) hears the FMU's MAVLink heartbeats at 57600 baud."""

from pymavlink import mavutil

from hil.system import SystemConfig, build_system

MS = 1_000_000


def test_telem1_pty_carries_mavlink(tmp_path):
    orch, dev = build_system(SystemConfig(seed=1, out_dir=str(tmp_path), mode="local",
                                          rc=None, telem_pty=True))
    with orch:
        pty = dev["telem1"].pty_name
        gcs = mavutil.mavlink_connection(pty, baud=57600)
        try:
            hb = None
            for _ in range(300):
                orch.run(duration_ns=10 * MS)
                hb = gcs.recv_match(type="HEARTBEAT", blocking=False)
                if hb is not None:
                    break
            assert hb is not None, "no HEARTBEAT on the TELEM1 pty"
            assert hb.autopilot == mavutil.mavlink.MAV_AUTOPILOT_PX4
        finally:
            gcs.close()
            for name in ("telem1", "telem2"):
                dev[name].close()
