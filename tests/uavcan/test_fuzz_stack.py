"""Fuzzing what the FMU's DroneCAN stack does with what other nodes send: well-formed transfers
whose fields take any value their DSDL type allows (NaN, infinities, extremes: GNSS fixes,
compass fields, ESC status, NodeStatus, GetNodeInfo answers, allocation requests), mixed with
random frames. Nothing may raise, and what reaches uORB stays within its types."""

from __future__ import annotations

import math

import can
import dronecan
from hypothesis import given
from hypothesis import strategies as st

from board.kernel import Kernel
from firmware.drivers.uavcan.esc_output import EscOutput
from firmware.drivers.uavcan.stack import DronecanStack
from firmware.lib.uavcan.transfer import encode
from firmware.platform import Platform
from tests.fuzzing import fuzz

U = dronecan.uavcan
anyfloat = st.floats(allow_nan=True, allow_infinity=True, width=32)


class _Ctrl:
    """A bxCAN that accepts every frame (the stack's answers are not under test here)."""

    def send(self, msg: can.Message) -> bool:
        return True

    def abort(self) -> None:
        pass


@st.composite
def transfer(draw: st.DrawFn) -> list[can.Message]:
    src = draw(st.integers(2, 127))  # 0 is anonymous (allocation only), 1 the FMU
    tid = draw(st.integers(0, 31))
    kind = draw(st.integers(0, 5))
    if kind == 0:
        f = U.equipment.gnss.Fix2(
            latitude_deg_1e8=draw(st.integers(-(2**36), 2**36 - 1)),
            longitude_deg_1e8=draw(st.integers(-(2**36), 2**36 - 1)),
            height_msl_mm=draw(st.integers(-(2**26), 2**26 - 1)),
            sats_used=draw(st.integers(0, 63)), status=draw(st.integers(0, 3)))
        f.ned_velocity = [draw(anyfloat) for _ in range(3)]
        f.covariance = [draw(anyfloat) for _ in range(draw(st.integers(0, 6)))]
        return encode(f, src, tid)
    if kind == 1:
        m = U.equipment.ahrs.MagneticFieldStrength2(sensor_id=draw(st.integers(0, 255)))
        m.magnetic_field_ga = [draw(anyfloat) for _ in range(3)]
        return encode(m, src, tid)
    if kind == 2:
        s = U.equipment.esc.Status(error_count=draw(st.integers(0, 2**32 - 1)),
                                   voltage=draw(anyfloat), current=draw(anyfloat),
                                   temperature=draw(anyfloat),
                                   rpm=draw(st.integers(-(2**17), 2**17 - 1)),
                                   power_rating_pct=draw(st.integers(0, 127)),
                                   esc_index=draw(st.integers(0, 31)))
        return encode(s, src, tid)
    if kind == 3:
        return encode(U.protocol.NodeStatus(uptime_sec=draw(st.integers(0, 2**32 - 1)),
                                            health=draw(st.integers(0, 3)),
                                            mode=draw(st.integers(0, 7))), src, tid)
    if kind == 4:
        r = U.protocol.GetNodeInfo.Response()
        r.name = draw(st.binary(max_size=80))
        return encode(r, src, tid, dest=1)
    a = U.protocol.dynamic_node_id.Allocation(node_id=draw(st.integers(0, 127)),
                                               first_part_of_unique_id=draw(st.booleans()))
    a.unique_id = list(draw(st.binary(max_size=6)))  # a part: one anonymous frame
    return encode(a, 0, tid)


random_frame = st.builds(lambda aid, ext, data: [can.Message(arbitration_id=aid,
                                                             is_extended_id=ext, data=data)],
                         st.integers(0, 0x1FFFFFFF), st.booleans(), st.binary(max_size=8))


@fuzz(examples=120)
@given(batches=st.lists(transfer() | random_frame, max_size=25))
def test_stack_takes_any_transfer_from_the_bus(batches):
    platform = Platform(Kernel("fuzz"))
    stack = DronecanStack(platform, _Ctrl(), node_id=1, dna=True, sub_gps=True, sub_mag=True,
                          unique_id=bytes(16))
    stack.esc = EscOutput()
    now = 0
    for frames in batches:
        now += 7_000
        for msg in frames:
            stack.receive(msg, now)
        stack.tick(now)
    for node_id in stack.nodes:
        assert 0 <= node_id <= 127
    m = platform.orb.new("esc_status")
    stack.esc.fill_status(m, now)
    assert 0 <= m.esc_count <= 8
