"""``hil fly --uart gps=socket://... --uart rc=/dev/pts/N``.

The FMU's GPS port is bound to a u-blox receiver on a TCP port (the project's u-blox model run
in wall time by a test server, which first answers with noise): the FMU's GPS driver
configures it through the binding (its move to 115200 baud applied to the port) and gets a 3D
fix on ``sensor_gps`` (PX4's vehicle_gps_position); a frame with a bad checksum injected then
is counted by the driver and the fix stays; when the receiver's end of the connection closes,
the binding reports it and the emulator keeps running. The IO's S.BUS input is bound to a pty pair at the same time: frames written to it
reach the FMU's ``input_rc``."""

from __future__ import annotations

import os
import random
import re

import pytest

from hil.rc.sbus import us_to_sbus_raw
from hil.system import SystemConfig, build_system
from ioproc.rc.sbus import encode_sbus_frame

from .ublox_server import UbloxServer

NS_PER_S = 1_000_000_000


@pytest.mark.paced
def test_gps_on_a_socket_gives_a_fix_and_survives_its_loss_rc_on_a_pty_reaches_the_fmu(
        tmp_path):
    # UBX NAV-PVT header with a short payload and a wrong checksum, inside random bytes
    bad_frame = bytes([0xB5, 0x62, 0x01, 0x07, 0x04, 0x00, 1, 2, 3, 4, 0x00, 0x00])
    noise = random.Random(1).randbytes(300)
    server = UbloxServer(garbage=noise)
    log: list[str] = []
    # an S.BUS receiver on the IO's RC input, behind one end of a pty pair
    rc_master, rc_slave = os.openpty()
    # paced, as in hil fly: the receiver runs in wall time, and an unpaced emulator on a busy
    # machine can outrun it by more than the driver's 1 s NAV-PVT timeout
    orch, dev = build_system(SystemConfig(seed=1, out_dir=str(tmp_path), mode="local", rc=None,
                                          speed=1.0, uart_bind={"gps": server.url,
                                                                "rc": os.ttyname(rc_slave)}))
    os.close(rc_slave)
    sticks = [us_to_sbus_raw(1500)] * 16
    sticks[2] = us_to_sbus_raw(1100)  # throttle low
    sticks[5] = us_to_sbus_raw(1900)
    sbus = encode_sbus_frame(sticks)
    binding = dev["uart_bindings"]["gps"]
    binding.log = log.append
    try:
        with orch:
            fix = None
            step = 0
            while orch.t_ns < 12 * NS_PER_S:
                os.write(rc_master, sbus)  # one frame every 14 ms, as S.BUS receivers send
                orch.run(duration_ns=14_000_000)
                step += 1
                gps = orch.call("fmu", "topic", "sensor_gps") if step % 16 == 0 else None
                if gps is not None and gps["fix_type"] >= 3:
                    fix = gps
                    break
            assert fix is not None, (binding.stats(), orch.call("fmu", "shell", "gps status"))
            assert abs(fix["lat"] / 1e7 - 47.397742) < 1e-3, fix
            assert binding.bytes_in >= 300 and server.bytes_from_client > 0
            rc = orch.call("fmu", "topic", "input_rc")
            assert rc is not None and abs(rc["values"][5] - 1900) <= 2, rc
            assert abs(rc["values"][2] - 1100) <= 2, rc

            def bad_checksums() -> int:
                status = orch.call("fmu", "shell", "gps status")[1]
                m = re.search(r"bad checksum: (\d+) events", status)
                assert m, status
                return int(m.group(1))

            before = bad_checksums()
            server.inject(noise.replace(b"\xb5", b"\x00") + bad_frame)
            end = orch.t_ns + 2 * NS_PER_S
            while bad_checksums() == before and orch.t_ns < end:
                os.write(rc_master, sbus)
                orch.run(duration_ns=14_000_000)
            assert bad_checksums() > before  # the firmware's parser counted it and went on
            orch.run(duration_ns=NS_PER_S // 2)
            assert orch.call("fmu", "topic", "sensor_gps")["fix_type"] >= 3
            # the driver found the receiver at its first scan rate, then moved it to 115200
            assert binding.stats()["baud_changes"] >= 1 and binding.serial.baudrate == 115_200
            server.drop_client()  # the device goes away mid-run
            t = orch.t_ns
            orch.run(duration_ns=NS_PER_S)
            assert binding.closed and any("UART binding gps=" in line for line in log), log
            assert orch.t_ns >= t + NS_PER_S and not orch.dead
    finally:
        server.close()
        binding.close()
        dev["uart_bindings"]["rc"].close()
        os.close(rc_master)
