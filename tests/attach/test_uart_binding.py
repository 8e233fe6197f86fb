"""``hil fly --uart gps=socket://...``: the FMU's GPS port bound to a u-blox receiver on a TCP
port (the project's u-blox model run in wall time by a test server, which first answers with
garbage and a frame with a bad checksum):
the FMU's GPS driver configures it through the binding (its move to 115200 baud applied to the
port) and gets a 3D fix on ``sensor_gps`` (PX4's vehicle_gps_position); when the receiver's end
of the connection closes, the binding reports it and the emulator keeps running."""

from __future__ import annotations

import random
import re

from hil.system import SystemConfig, build_system

from .ublox_server import UbloxServer

NS_PER_S = 1_000_000_000


def test_gps_port_bound_to_a_socket_gives_a_fix_and_survives_its_loss(tmp_path):
    # UBX NAV-PVT header with a short payload and a wrong checksum, inside random bytes
    bad_frame = bytes([0xB5, 0x62, 0x01, 0x07, 0x04, 0x00, 1, 2, 3, 4, 0x00, 0x00])
    noise = random.Random(1).randbytes(300)
    server = UbloxServer(garbage=noise.replace(b"\xb5", b"\x00") + bad_frame)
    log: list[str] = []
    orch, dev = build_system(SystemConfig(seed=1, out_dir=str(tmp_path), mode="local", rc=None,
                                          uart_bind={"gps": server.url}))
    binding = dev["uart_bindings"]["gps"]
    binding.log = log.append
    try:
        with orch:
            fix = None
            while orch.t_ns < 12 * NS_PER_S:
                orch.run(duration_ns=NS_PER_S // 4)
                gps = orch.call("fmu", "topic", "sensor_gps")
                if gps is not None and gps["fix_type"] >= 3:
                    fix = gps
                    break
            assert fix is not None, (binding.stats(), orch.call("fmu", "shell", "gps status"))
            assert abs(fix["lat"] / 1e7 - 47.397742) < 1e-3, fix
            assert binding.bytes_in >= 312 and server.bytes_from_client > 0
            status = orch.call("fmu", "shell", "gps status")[1]
            bad = re.search(r"bad checksum: (\d+) events", status)
            assert bad and int(bad.group(1)) >= 1, status  # the firmware counted and skipped
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
