"""The FMU halted, the FMU-IO link cut, noise on it: the IO and the FMU's px4io driver notice
as on hardware (two board processes, the real firmware on both)."""

from __future__ import annotations

import pytest

from hil.faults import FaultError

from .conftest import MS, S

pytestmark = pytest.mark.slow
IO_FMU_LOSS_S = 0.5          # E14: FMU lost 500 ms after the last CONTROLS write


def test_fmu_hang_trips_the_io_and_release_resumes(rig):
    orch = rig.orch
    before = orch.call("fmu", "topic", "px4io_status")["_count"]
    t_hang = orch.t_ns
    rig.start("board.fmu_hang")
    assert orch.call("fmu", "hung")
    took = rig.run_until(lambda: "FMU_OK" not in rig.io_flags(), timeout_s=2)
    assert IO_FMU_LOSS_S - 0.01 <= took <= IO_FMU_LOSS_S + 0.05
    assert "FMU_LOST" in orch.call("io", "status")["alarm_names"]
    # halted, not dead: the process answers, publishes nothing, and its clock follows
    rig.run_s(0.5)
    assert "fmu" not in orch.dead
    assert orch.call("fmu", "topic", "px4io_status")["_count"] == before
    assert orch.call("fmu", "time_ns") == orch.t_ns
    assert (orch.t_ns - t_hang) >= S
    rig.stop("board.fmu_hang", "", None)
    assert not orch.call("fmu", "hung")
    rig.run_until(lambda: "FMU_OK" in rig.io_flags(), timeout_s=1)
    rig.run_s(0.2)
    assert orch.call("fmu", "topic", "px4io_status")["_count"] > before + 5


def test_fmu_to_io_wire_cut_the_io_fails_safe_and_the_fmu_reports_the_io_lost(rig):
    orch = rig.orch
    token = rig.start("bus.fmu_io_link_cut", "fmu_to_io")
    assert orch.wire_faults() == ["fmu.io_link"]
    took = rig.run_until(lambda: "FMU_OK" not in rig.io_flags(), timeout_s=2)
    assert IO_FMU_LOSS_S - 0.01 <= took <= IO_FMU_LOSS_S + 0.05
    # the px4io driver hears no replies: 10 calls x 3 tries x 10 ms
    rig.run_until(lambda: any("IO lost" in m for m in rig.dmesg()), timeout_s=1.5)
    st = orch.call("fmu", "topic", "px4io_status")
    assert st["link_errors"] >= 30
    rig.stop("bus.fmu_io_link_cut", "fmu_to_io", token)
    assert orch.wire_faults() == []
    rig.run_until(lambda: "FMU_OK" in rig.io_flags(), timeout_s=1)
    rig.run_until(lambda: any("IO link restored" in m for m in rig.dmesg()), timeout_s=1)
    with pytest.raises(FaultError, match="target"):
        rig.start("bus.fmu_io_link_cut", "sideways")
    with pytest.raises(FaultError, match="no wire"):
        rig.start("bus.wire_cut", "io.nowhere")


def test_noise_on_the_fmu_to_io_line_costs_retries_not_the_link(rig):
    orch = rig.orch
    e0 = orch.call("fmu", "topic", "px4io_status")["link_errors"]
    c0 = orch.call("io", "status")["link"]["corrupt"]
    token = rig.start("bus.uart_noise", "io.USART2", bit_error_rate=2e-4)
    rig.run_s(2.0)
    stats = orch.call("io", "uart_fault_stats", "USART2")
    st = orch.call("fmu", "topic", "px4io_status")
    io = orch.call("io", "status")
    # ~25 kB/s towards the IO: at 2e-4 per bit about 50 damaged frames a second
    assert stats["bytes"] > 20_000
    damaged = stats["corrupted"] + stats["dropped"] + stats["framing_errors"]
    expected = stats["bytes"] * 10 * 2e-4
    assert 0.6 * expected < damaged < 1.4 * expected
    assert io["link"]["corrupt"] + io["link"]["line_errors"] > c0   # the IO's CRC caught them
    assert st["link_errors"] > e0                                  # the FMU retried
    assert "FMU_OK" in io["flag_names"]                            # and the link held
    assert not any("IO lost" in m for m in rig.dmesg())
    rig.stop("bus.uart_noise", "io.USART2", token)
    assert orch.call("io", "uart_fault_stats", "USART2") == {}
    with pytest.raises(FaultError, match="no UART"):
        rig.start("bus.uart_noise", "io.USART9")
    with pytest.raises(FaultError, match="no board"):
        rig.start("bus.uart_noise", "gps.USART1")
