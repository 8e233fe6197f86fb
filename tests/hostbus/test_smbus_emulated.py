"""hil/smbus_emulated.py: smbus2's SMBus API answered by the device models of an emulated I2C
bus, so scripts written against smbus2 run on the virtual board: the register semantics are the
chip's, failures are OSErrors with Linux's I2C fault codes, bad arguments are refused before
they reach the bus."""

from __future__ import annotations

import errno

import pytest
from hypothesis import given
from hypothesis import strategies as st
from smbus2 import i2c_msg

from board.i2c import I2cBus, I2cFault, I2cTarget
from board.kernel import Kernel
from hil.smbus_emulated import EmulatedSMBus
from peripherals.errors import rng_for
from peripherals.hmc5883 import Hmc5883
from tests.fuzzing import fuzz
from tests.hostbus.rigs import environment

MAG = 0x1E


class _OneByteOnly(I2cTarget):
    """ACKs its address and one data byte, NAKs the next (a chip that takes no more)."""

    def _start(self, t_ns: int, is_read: bool) -> bool:
        return True

    def _write(self, t_ns: int, data: bytes) -> int:
        return min(1, len(data))

    def _read(self, t_ns: int, n: int) -> bytes:
        return b"\x5a" * n


@pytest.fixture
def rig():
    k = Kernel("t")
    bus = I2cBus(k, "I2C1", clock_hz=400_000)
    bus.attach(MAG, Hmc5883(k, environment(), rng_for(1, "hmc5883")))
    bus.attach(0x30, _OneByteOnly())
    return k, bus, EmulatedSMBus(bus)


def test_register_calls_follow_the_chip(rig) -> None:
    k, _bus, sm = rig
    assert sm.read_byte_data(MAG, 0x0A) == ord("H")
    assert sm.read_i2c_block_data(MAG, 0x0A, 3) == list(b"H43")
    sm.write_byte_data(MAG, 0x00, 0x70)
    assert sm.read_byte_data(MAG, 0x00) == 0x70
    sm.write_i2c_block_data(MAG, 0x00, [0x18, 0x20])
    assert sm.read_i2c_block_data(MAG, 0x00, 2) == [0x18, 0x20]
    assert sm.read_word_data(MAG, 0x00) == 0x18 | 0x20 << 8          # SMBus words: LSB first
    sm.write_word_data(MAG, 0x00, 0x4010)
    assert sm.read_i2c_block_data(MAG, 0x00, 2) == [0x10, 0x40]
    sm.write_byte(MAG, 0x0B)                                         # set the pointer only
    assert sm.read_byte(MAG) == ord("4")
    sm.write_quick(MAG)
    before = k.busy_ns
    sm.read_byte_data(MAG, 0x0A)                 # 39 SCL clocks at 400 kHz, as on the wires
    assert k.busy_ns - before == 97_500


def test_i2c_rdwr_with_smbus2_messages(rig) -> None:
    _k, _bus, sm = rig
    w, r = i2c_msg.write(MAG, [0x0A]), i2c_msg.read(MAG, 3)
    sm.i2c_rdwr(w, r)
    assert bytes(r) == b"H43" and list(r) == [0x48, 0x34, 0x33]
    sm.i2c_rdwr(i2c_msg.write(MAG, [0x0C]))
    r1 = i2c_msg.read(MAG, 1)
    sm.i2c_rdwr(r1)
    assert bytes(r1) == b"3"
    with pytest.raises(OSError) as exc:
        sm.i2c_rdwr(i2c_msg.write(MAG, [0]), i2c_msg.write(MAG, [1]))
    assert exc.value.errno == errno.EOPNOTSUPP
    with pytest.raises(OSError) as exc:
        sm.i2c_rdwr(i2c_msg.write(MAG, [0]), i2c_msg.read(0x30, 1))
    assert exc.value.errno == errno.EOPNOTSUPP
    with pytest.raises(TypeError, match="i2c_msg"):
        sm.i2c_rdwr(b"\x0a")
    with pytest.raises(ValueError, match="no messages"):
        sm.i2c_rdwr()


def test_failures_are_oserrors_with_linux_fault_codes(rig) -> None:
    _k, bus, sm = rig
    with pytest.raises(OSError) as exc:
        sm.read_byte_data(0x50, 0)                    # nobody there: address NAK
    assert exc.value.errno == errno.ENXIO
    with pytest.raises(OSError) as exc:
        sm.write_i2c_block_data(0x30, 0x00, [1, 2])   # second data byte NAKed
    assert exc.value.errno == errno.EIO
    sm.write_byte(0x30, 0x00)                         # one byte is ACKed
    bus.set_fault(I2cFault(sda_stuck=True))
    with pytest.raises(OSError) as exc:
        sm.read_byte_data(MAG, 0x0A)
    assert exc.value.errno == errno.ETIMEDOUT
    bus.set_fault(None)
    assert sm.read_byte_data(MAG, 0x0A) == ord("H")


@pytest.mark.parametrize("call, match", [
    (lambda sm: sm.read_i2c_block_data(MAG, 0, 33), "length"),
    (lambda sm: sm.read_i2c_block_data(MAG, 0, 0), "length"),
    (lambda sm: sm.write_i2c_block_data(MAG, 0, list(range(33))), "32"),
    (lambda sm: sm.write_i2c_block_data(MAG, 0, [256]), "bytes"),
    (lambda sm: sm.write_byte_data(MAG, 0, 256), "value"),
    (lambda sm: sm.read_byte_data(MAG, -1), "register"),
    (lambda sm: sm.write_word_data(MAG, 0, 0x10000), "value"),
    (lambda sm: sm.read_byte(0x80), "7-bit"),
])
def test_bad_arguments_never_reach_the_bus(rig, call, match) -> None:
    _k, bus, sm = rig
    n = bus.transactions
    with pytest.raises(ValueError, match=match):
        call(sm)
    assert bus.transactions == n


def test_close_and_context_manager(rig) -> None:
    _k, bus, _sm = rig
    with EmulatedSMBus(bus) as sm:
        assert sm.read_byte_data(MAG, 0x0A) == ord("H")
    assert sm.closed
    with pytest.raises(OSError) as exc:
        sm.read_byte_data(MAG, 0x0A)
    assert exc.value.errno == errno.EBADF
    with pytest.raises(TypeError, match="I2cBus"):
        EmulatedSMBus("/dev/i2c-1")  # type: ignore[arg-type]


_ARG = st.one_of(st.integers(-300, 70_000), st.none(), st.text(max_size=3),
                 st.lists(st.integers(-2, 300), max_size=40), st.binary(max_size=40),
                 st.floats(allow_nan=True))
_CALLS = ("write_quick", "read_byte", "write_byte", "read_byte_data", "write_byte_data",
          "read_word_data", "write_word_data", "read_i2c_block_data", "write_i2c_block_data")


@fuzz(examples=150)
@given(calls=st.lists(st.tuples(st.sampled_from(_CALLS), st.sampled_from([MAG, 0x30, 0x50]),
                                st.lists(_ARG, min_size=1, max_size=3)), max_size=12))
def test_random_script_calls_raise_only_documented_errors(calls) -> None:
    """A script's calls with any arguments: an answer, or ValueError/TypeError (bad argument)
    or OSError (the bus said no); the chip and the bus stay usable."""
    k = Kernel("t")
    bus = I2cBus(k, "I2C1")
    bus.attach(MAG, Hmc5883(k, environment(), rng_for(1, "hmc5883")))
    bus.attach(0x30, _OneByteOnly())
    sm = EmulatedSMBus(bus)
    for name, addr, args in calls:
        method = getattr(sm, name)
        n_args = {"write_quick": 0, "read_byte": 0, "write_byte": 1, "read_byte_data": 1,
                  "read_word_data": 1}.get(name, 2)
        args = (args * 3)[:n_args]
        try:
            method(addr, *args)
        except (ValueError, TypeError, OSError):
            pass
    sm.write_byte_data(MAG, 0x00, 0x10)
    assert sm.read_i2c_block_data(MAG, 0x00, 1) == [0x10]
