"""The FMU's nsh console reached from the host: a scripted session over the pseudo-terminal
(pyserial on the pty the bridge opens) runs the shell's commands and checks their output;
the same console over TCP answers `hil shell -c`."""

import threading
import time

import pytest
import serial

from board.wiring import WORLD, uart_link
from hil.console import SerialBridge
from hil.devices import DeviceHub
from hil.orchestrator import BoardSpec, Orchestrator
from hil.shell_client import run_command

MS = 1_000_000


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    d = tmp_path_factory.mktemp("fmu")
    (d / "sd").mkdir()
    bridge = SerialBridge("console", poll_every=1)
    orch = Orchestrator(
        {"fmu": BoardSpec("fmu.board:FmuV2Board",
                          {"fram_path": str(d / "fram.bin"), "sd_root": str(d / "sd")})},
        uart_link(("fmu", "console"), (WORLD, "console")), world=DeviceHub(bridge),
        mode="local")
    orch.start()
    orch.run(duration_ns=1500 * MS)  # boot, rcS, GPS configured
    port = serial.Serial(bridge.pty_name, 57600, timeout=0)
    port.read(65536)  # the boot output

    def ask(line, budget_s=30.0):
        port.write(line.encode() + b"\r")
        buf = bytearray()
        t_end = orch.t_ns + int(budget_s * 1e9)
        while b"nsh> " not in buf and orch.t_ns < t_end:
            orch.run(duration_ns=20 * MS)
            buf += port.read(65536)
        assert b"nsh> " in buf, f"no prompt after {line!r}: {bytes(buf)[-300:]!r}"
        text = bytes(buf).split(b"nsh> ", 1)[0].decode()
        return text.replace("\r\n", "\n").split("\n", 1)[1]  # drop the echoed line

    yield orch, bridge, ask, port
    port.close()
    orch.close()
    bridge.close()


def test_scripted_session_over_the_pty(session):
    _orch, _bridge, ask, _port = session
    help_text = ask("help")
    for cmd in ("param", "listener", "top", "dmesg", "mpu6000"):
        assert cmd in help_text
    assert "HW arch: PX4_FMU_V2" in ask("ver all")
    ps = ask("ps")
    assert "wq:SPI1" in ps and "mpu6000" in ps
    top = ask("top once")
    assert "mpu6000" in top
    uorb = ask("uorb top")
    assert "sensor_gyro" in uorb
    listener = ask("listener sensor_baro -n 1")
    assert "pressure" in listener
    assert "wq:SPI1" in ask("work_queue status")
    assert "mpu6000: read" in ask("perf")
    assert "started" in ask("dmesg")
    assert ask("free")
    assert "SYS_AUTOSTART" in ask("param show SYS_AUTO*")
    ask("param set SDLOG_PROFILE 3")
    assert "3" in ask("param get SDLOG_PROFILE")
    ask("param save")
    assert "saved" in ask("dmesg").splitlines()[-1]
    assert "mpu6000: running" in ask("mpu6000 status")
    assert "command not found" in ask("definitely_not_a_command")
    assert "parameter NO_SUCH_PARAM not found" in ask("param set NO_SUCH_PARAM 1")
    assert "HW arch" in ask("ver all")  # the shell went on after the errors
    # the rest of param, over the same line
    assert ask("param compare SDLOG_PROFILE 3") == "" and ask("echo $?").strip() == "0"
    ask("param greater SDLOG_PROFILE 5")
    assert ask("echo $?").strip() == "1"
    assert "parameters" in ask("param status")
    ask("param export /fs/microsd/params.txt")
    ask("param set SDLOG_PROFILE 1")
    ask("param import /fs/microsd/params.txt")
    assert ask("param get SDLOG_PROFILE").strip() == "3"
    ask("param reset SDLOG_PROFILE")
    assert ask("param get SDLOG_PROFILE").strip() == "1"
    ask("param set SDLOG_PROFILE 7")
    ask("param reset_all")
    assert ask("param get SDLOG_PROFILE").strip() == "1"
    ask("param load")
    # a module's life cycle from the console
    ask("ms5611 stop")
    assert "not running" in ask("ms5611 status")
    ask("ms5611 start")
    assert "ms5611: running" in ask("ms5611 status")


def test_reboot_from_the_console(session):
    orch, _bridge, ask, port = session
    port.write(b"reboot\r")
    before = orch.reboots.get("fmu", 0)
    for _ in range(100):
        orch.run(duration_ns=20 * MS)
        if orch.reboots.get("fmu", 0) > before:
            break
    assert orch.reboots.get("fmu", 0) == before + 1
    orch.run(duration_ns=1500 * MS)  # the new board boots and runs rcS on the console
    port.read(1 << 20)                 # its boot output
    assert "HW arch: PX4_FMU_V2" in ask("ver all")
    assert "rebooting" not in ask("dmesg")  # a fresh dmesg: a new board

def test_tcp_console_answers_hil_shell(session):
    orch, bridge, _ask, _port = session
    result = {}
    th = threading.Thread(target=lambda: result.update(
        out=run_command(bridge.tcp_port, "param get SYS_USE_IO", timeout_s=20)))
    th.start()
    deadline = time.monotonic() + 30
    while th.is_alive() and time.monotonic() < deadline:
        orch.run(duration_ns=20 * MS)
    th.join(timeout=1)
    assert result["out"].strip() == "1"
