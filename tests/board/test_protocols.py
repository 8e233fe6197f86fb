"""The typed contracts of board/protocols.py and hil/devices.py hold at run time too.

mypy checks the implementations against the protocols where they meet (``System(hw=board)``,
``Orchestrator(world=...)``, the handles dict); this test checks the same members by name on the
objects themselves, cheaply, so a renamed method (``spi_handle``) or a handle without ``alive``
fails here even when nobody runs mypy. Nothing in the product checks protocols at run time
(they are erased; no ``isinstance``).
"""

from __future__ import annotations

import inspect
import re
import typing

import pytest

from board.endpoint import LocalHandle
from fmu.board import FmuV2Board
from board.protocols import BoardHandle, BoardHardware
from hil.boardproc import OffsetHandle, ProcessHandle
from hil.devices import DeviceHub, HostDevice
from hil.worldlink import WorldPorts


def members(protocol: type) -> set[str]:
    """The names a protocol declares (methods, properties and attributes)."""
    return set(typing._get_protocol_attrs(protocol))  # type: ignore[attr-defined]


def init_attributes(cls: type) -> set[str]:
    """Attributes ``__init__`` assigns on ``self`` (for a class too costly to build here)."""
    return set(re.findall(r"self\.(\w+)(?::[^=\n]*)? =", inspect.getsource(cls.__init__)))


def test_the_fmu_board_is_the_hardware_its_system_sees():
    board = FmuV2Board(firmware="none")
    assert members(BoardHardware) == {"spec", "i2c", "uarts", "gpio", "adc", "spi_handle",
                                      "uart_by_device"}
    missing = {m for m in members(BoardHardware) if not hasattr(board, m)}
    assert not missing
    place = board.spec.place("mpu6000")
    assert board.spi_handle(place.name).max_speed_hz > 0
    assert board.uart_by_device("/dev/ttyS3") is board.uarts["UART4"]


def test_a_system_is_built_with_its_board_not_patched_after():
    from firmware.system import System

    board = FmuV2Board(firmware="none")
    system = System(board.platform, hw=board)
    assert system.hw is board and system.adc is board.adc      # the battery monitor's ADC
    bare = System(board.platform)                              # a test's system: no board
    assert bare.hw is None and bare.adc is None and bare.waypoints_partition is None


@pytest.mark.parametrize("cls", [LocalHandle, ProcessHandle])
def test_board_handles_have_what_the_orchestrator_uses(cls):
    have = {m for m in members(BoardHandle) if hasattr(cls, m)} | init_attributes(cls)
    assert members(BoardHandle) <= have, members(BoardHandle) - have


def test_a_rebooted_boards_handle_passes_the_rest_to_the_new_one():
    handle = LocalHandle("fmu", "fmu.board:FmuV2Board", {"firmware": "none"})
    offset = OffsetHandle(handle, 5_000_000)
    assert all(hasattr(offset, m) for m in members(BoardHandle))
    assert offset.is_alive() and offset.ports == handle.ports
    offset.close()
    assert not handle.alive


@pytest.mark.parametrize("cls", [WorldPorts, DeviceHub])
def test_the_world_and_the_hub_are_host_devices(cls):
    assert members(HostDevice) == {"ports", "run_until", "outputs", "input"}
    assert all(hasattr(cls, m) for m in members(HostDevice))
