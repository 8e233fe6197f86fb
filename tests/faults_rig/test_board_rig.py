"""The fault catalogue on boards built in the test: :class:`hil.faults.BoardRig`.

Each test builds an FMU (or the IO) in-process, applies a catalogue kind by name through the
rig, runs the board's kernel and asserts what PX4's drivers and modules do about it (their
error counters, dmesg, the sensors module's voter), then that a fault with a duration stops by
itself at its virtual end and the board recovers. No orchestrator, no other process.
"""

from __future__ import annotations

import dataclasses

import pytest

from fmu.board import BOOT_TO_SENSORS_NS, FmuV2Board
from board.specs import FMU_V2, I2cDevice
from hil.faults import BoardRig, FaultError, get_kind
from hil.turntable import Turntable
from board.uart import Uart, UartConfig, UartWire
from ioproc.board import IoV2Board
from ioproc.protocol import PageNo, Status, decode_reply, encode_read

S = 1_000_000_000
MS = 1_000_000


def _board(firmware: str = "sensors", spec=FMU_V2, run_ns: int = BOOT_TO_SENSORS_NS + S
           ) -> FmuV2Board:
    board = FmuV2Board(seed=3, firmware=firmware, spec=spec)
    Turntable(board.kernel, board.env, alt_m=488.0)
    board.kernel.run(run_ns)
    return board


def _dmesg(board: FmuV2Board, source: str, since_ns: int = 0) -> list[str]:
    return [m[3] for m in board.ctl_dmesg() if m[2] == source and m[0] * 1000 >= since_ns]


def _pubs(board: FmuV2Board, topic: str, instance: int) -> int:
    return board.platform.orb.node(topic, instance).publish_count


def test_an_i2c_nak_storm_silences_the_compass_until_it_stops_by_itself():
    board = _board()
    rig = BoardRig(board)
    drv = board.drivers["hmc5883"]
    err0, t0 = drv.error_count, board.kernel.now_ns
    af = rig.start("bus.i2c_nak_storm", "fmu.I2C1", duration_s=0.3)
    board.kernel.run_for(100 * MS)
    pubs = _pubs(board, "sensor_mag", 1)
    board.kernel.run_for(150 * MS)
    assert _pubs(board, "sensor_mag", 1) == pubs             # nothing gets through
    assert drv.error_count - err0 >= 20                      # every NAK a bad transfer
    assert any("no ACK from 0x1E" in t for t in _dmesg(board, "hmc5883", t0))
    assert board.ctl_bus_stats("i2c", "I2C1")["nak_count"] > 0
    board.kernel.run_for(250 * MS)                           # past the fault's end
    assert not af.active and af.t_stop_ns == t0 + 300 * MS   # stopped on the kernel's clock
    assert _pubs(board, "sensor_mag", 1) > pubs + 5          # the compass is back


def test_a_wrong_identity_register_is_found_and_reset_by_the_driver():
    board = _board()
    rig = BoardRig(board)
    drv = board.drivers["l3gd20"]
    err0, t0 = drv.error_count, board.kernel.now_ns
    af = rig.start("sensor.wrong_id", "l3gd20", {"value": 0x00})
    board.kernel.run_for(300 * MS)
    texts = _dmesg(board, "l3gd20", t0)
    assert any("register 0x0F read 0x00, expected 0xD4" in t for t in texts), texts
    assert any("reset failed: WHO_AM_I 0x00" in t for t in texts), texts
    assert drv.error_count > err0
    pubs = _pubs(board, "sensor_gyro", 1)
    board.kernel.run_for(100 * MS)
    assert _pubs(board, "sensor_gyro", 1) == pubs            # given up on until it answers
    rig.stop(af)
    board.kernel.run_for(1500 * MS)
    assert _pubs(board, "sensor_gyro", 1) > pubs + 100       # re-probed and publishing


def test_a_stuck_spi_miso_makes_every_driver_on_the_bus_see_all_ones():
    board = _board()
    rig = BoardRig(board)
    drivers = [board.drivers[n] for n in ("mpu6000", "l3gd20", "lsm303d")]
    errs = [d.error_count for d in drivers]
    t0 = board.kernel.now_ns
    rig.start("bus.spi_miso_stuck", "fmu.SPI1", {"level_high": 1}, duration_s=0.2)
    board.kernel.run_for(150 * MS)
    assert all(d.error_count > e for d, e in zip(drivers, errs))
    assert any("0xFF" in t for t in _dmesg(board, "mpu6000", t0))
    assert _pubs(board, "sensor_mag", 1) > 0                 # I2C1 is another bus
    board.kernel.run_for(1000 * MS)
    pubs = _pubs(board, "sensor_accel", 0)
    board.kernel.run_for(100 * MS)
    assert _pubs(board, "sensor_accel", 0) > pubs + 50       # healed, back at 1 kHz


def test_the_voter_fails_over_when_the_primary_imu_goes_absent():
    board = _board("rcS", run_ns=3 * S)
    rig = BoardRig(board)
    status = board.ctl_topic("sensors_status_imu")
    primary, second = status["device_ids"][:2]
    assert status["device_id_primary"] == primary and status["failover_count"] == 0
    rig.start("sensor.absent", "mpu6000", duration_s=2.0)
    board.kernel.run_for(500 * MS)
    status = board.ctl_topic("sensors_status_imu")
    assert status["device_id_primary"] == second and status["failover_count"] == 1
    assert status["healthy"][:2] == [False, True]
    assert any("accel #0 failed, switching to #1" in t for t in _dmesg(board, "sensors"))
    board.kernel.run_for(2500 * MS)                          # the chip answers again
    assert board.ctl_topic("sensors_status_imu")["healthy"][:2] == [True, True]


def test_sensor_targets_come_from_the_boards_spec():
    """A variant without the barometer and with a second compass on I2C2: the sensor kinds'
    targets on it are its chips, not the standard FMUv2's."""
    i2c = tuple(dataclasses.replace(b, devices=b.devices + (
        I2cDevice("hmc5883_b", "hmc5883", 0x1E, external=True),)) if b.name == "I2C2" else b
        for b in FMU_V2.i2c)
    spi = tuple(dataclasses.replace(b, devices=tuple(d for d in b.devices if d.name != "ms5611"))
                for b in FMU_V2.spi)
    variant = dataclasses.replace(FMU_V2, spi=spi, i2c=i2c)
    board = FmuV2Board(seed=3, firmware="none", spec=variant)
    rig = BoardRig(board)
    kind = get_kind("sensor.absent")
    assert kind.targets_on(rig) == ("mpu6000", "l3gd20", "lsm303d", "hmc5883", "hmc5883_b")
    assert "ms5611" in kind.targets                          # the standard board's listing
    rig.start("sensor.absent", "hmc5883_b")
    assert board.devices["hmc5883_b"].faults.absent and not board.devices["hmc5883"].faults.absent
    with pytest.raises(FaultError, match="target 'ms5611' is not one of"):
        rig.start("sensor.stuck", "ms5611")
    assert get_kind("sensor.drdy_stuck").targets_on(rig)[-2:] == ("hmc5883", "hmc5883_b")


def test_the_io_board_takes_its_faults_too():
    """The servo rail sags at the IO's ADC; the IO reports it in its STATUS page, read here
    over its serial link as the FMU reads it."""
    io = IoV2Board()
    link = Uart(io.kernel, "fmu.USART6", UartConfig(1_500_000))
    UartWire(link, io.uarts["USART2"])

    def vservo_mv() -> int:
        link.write(encode_read(PageNo.STATUS, Status.VSERVO, 1))
        io.kernel.run_for(2 * MS)
        reply = decode_reply(link.read())
        assert reply.ok, reply
        return reply.values[0]

    io.kernel.run(1 * S)
    assert vservo_mv() == pytest.approx(5000, abs=20)
    rig = BoardRig(io)
    af = rig.start("board.servo_rail_brownout", params={"volts": 4.2}, duration_s=0.5)
    io.kernel.run_for(100 * MS)
    assert vservo_mv() == pytest.approx(4200, abs=20)
    io.kernel.run_for(500 * MS)
    assert not af.active
    assert vservo_mv() == pytest.approx(5000, abs=20)


def test_kinds_that_need_the_orchestrated_system_say_so():
    board = FmuV2Board(seed=3, firmware="none")
    rig = BoardRig(board)
    with pytest.raises(FaultError, match="board.crash acts on the orchestrated system"):
        rig.start("board.crash", "fmu")
    with pytest.raises(FaultError, match="^fault bus.wire_cut acts on the orchestrated"):
        rig.start("bus.wire_cut", "fmu.io_link")
    with pytest.raises(FaultError, match="no SPI bus 'SPI9' \\(buses: SPI1, SPI2\\)"):
        rig.start("bus.spi_miso_stuck", "fmu.SPI9")
    with pytest.raises(FaultError, match="no board 'io' \\(boards: fmu\\)"):
        rig.start("board.servo_rail_brownout")
    with pytest.raises(FaultError, match="this rig has no 'world' device"):
        rig.start("vehicle.wind")       # a world kind: this rig was given no world (dev)


def test_the_docs_example_runs():
    """docs/faults.md, "Faults on an in-process board": its example is executed as written."""
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / "docs" / "faults.md").read_text()
    section = text.split("### Faults on an in-process board", 1)[1]
    code = section.split("```python\n", 1)[1].split("```", 1)[0]
    exec(compile(code, "docs/faults.md", "exec"), {})
