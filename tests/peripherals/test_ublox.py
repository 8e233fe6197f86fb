"""u-blox M8 model, seen from a host UART only: NMEA at power-on, UBX configuration with
ACK/NAK, the baud switch, NAV-PVT layout and rate, bad input, faults.

Frames are built and decoded here with the test's own code and the offsets of the reference
sheet (sensors.md 8.2 and 8.6), not with the model's or the driver's helpers.
"""

from __future__ import annotations

import itertools
import struct

import pytest

from board.kernel import Kernel
from board.uart import FE, Uart, UartConfig, UartWire
from peripherals.errors import rng_for
from peripherals.physics import Environment
from peripherals.ublox import UbloxM8

MS = 1_000_000
S = 1_000_000_000


def fletcher(body: bytes) -> bytes:
    a = b = 0
    for x in body:
        a = (a + x) % 256
        b = (b + a) % 256
    return bytes((a, b))


def ubx(cls: int, msg_id: int, payload: bytes = b"") -> bytes:
    body = bytes((cls, msg_id)) + struct.pack("<H", len(payload)) + payload
    return b"\xb5\x62" + body + fletcher(body)


def frames(data: bytes) -> list[tuple[int, int, bytes]]:
    """Every well-formed UBX frame in a byte stream (NMEA and garbage skipped)."""
    out, i = [], 0
    while True:
        i = data.find(b"\xb5\x62", i)
        if i < 0 or i + 8 > len(data):
            return out
        n = data[i + 4] | data[i + 5] << 8
        end = i + 6 + n
        if end + 2 <= len(data) and data[end:end + 2] == fletcher(data[i + 2:end]):
            out.append((data[i + 2], data[i + 3], data[i + 6:end]))
            i = end + 2
        else:
            i += 1


class Bench:
    """A receiver wired to a host UART, with helpers to talk to it in virtual time."""

    def __init__(self, baud: int = 9600, ttff_s: float = 0.5, seed: int = 1,
                 env: Environment | None = None) -> None:
        self.k = Kernel("gps-test")
        self.env = env or Environment()
        self.host = Uart(self.k, "host", UartConfig(baud), rx_buffer_size=1 << 20)
        self.gps = UbloxM8(self.k, self.env, rng_for(seed, "gps"), baud=baud, ttff_s=ttff_s)
        UartWire(self.host, self.gps.uart)

    def run(self, ns: int) -> bytes:
        self.k.run_for(ns)
        return self.host.read()

    def cmd(self, cls: int, msg_id: int, payload: bytes = b"", wait_ns: int = 300 * MS) -> list:
        self.host.reset_input_buffer()
        self.host.write(ubx(cls, msg_id, payload))
        return frames(self.run(wait_ns))

    def baud(self, baud: int) -> None:
        self.host.config = UartConfig(baud)

    def ubx_only(self, baud: int, port_rate: tuple = ()) -> None:
        """CFG-PRT UART1 -> ``baud``, UBX out only; the host follows."""
        block = struct.pack("<BBHIIHHHH", 1, 0, 0, 0x8D0, baud, 0x21, 0x01, 0, 0)
        self.host.write(ubx(0x06, 0x00, block))
        self.run(200 * MS)
        self.baud(baud)
        self.run(20 * MS)


def nmea_ok(line: bytes) -> bool:
    body, _, cs = line[1:].partition(b"*")
    x = 0
    for c in body:
        x ^= c
    return line.startswith(b"$") and cs == f"{x:02X}".encode()


def test_reference_worked_frames():
    assert ubx(0x0A, 0x04) == bytes.fromhex("B5620A0400000E34")
    from peripherals.ublox.frame import ubx_frame
    assert ubx_frame(0x06, 0x08, bytes.fromhex("C80001000000")) == bytes.fromhex(
        "B56206080600C80001000000DD68")
    assert ubx_frame(0x06, 0x01, bytes((1, 7, 1))) == bytes.fromhex("B56206010300010701135 1"
                                                                    .replace(" ", ""))


def test_nmea_at_9600_from_power_on_with_valid_checksums():
    b = Bench(9600)
    data = b.run(3_500 * MS)
    lines = data.split(b"\r\n")[:-1]  # the last sentence may still be on the wire
    assert lines and all(nmea_ok(ln) for ln in lines)
    kinds = [ln[3:6] for ln in lines]
    for kind in (b"GGA", b"RMC", b"GSA", b"GSV", b"VTG"):
        assert kind in kinds
    assert kinds.count(b"GGA") == 3                     # 1 Hz: epochs at 1, 2, 3 s
    gga = [ln for ln in lines if ln[3:6] == b"GGA"][-1].split(b",")
    assert gga[6] == b"1" and 10 <= int(gga[7]) <= 14   # fix after the short TTFF
    assert abs(int(gga[2][:2]) + float(gga[2][2:]) / 60 - b.env.lat_deg) < 1e-4
    assert b.host.framing_errors == 0


def acks(got: list, msg_id: int) -> list[int]:
    """ACK ids (1 ACK, 0 NAK) received for CFG ``msg_id``."""
    return [f[1] for f in got if f[0] == 0x05 and f[2] == bytes((0x06, msg_id))]


def test_cfg_ack_poll_and_nak():
    b = Bench(38400)
    # CFG-RATE 200 ms: ACK-ACK exactly as in the reference.
    b.host.write(ubx(0x06, 0x08, struct.pack("<HHH", 200, 1, 0)))
    assert bytes.fromhex("B56205010200060816 3F".replace(" ", "")) in b.run(300 * MS)
    # Poll: the current value, then ACK.
    got = b.cmd(0x06, 0x08)
    assert (0x06, 0x08, struct.pack("<HHH", 200, 1, 0)) in got
    assert got.index((0x05, 0x01, b"\x06\x08")) > got.index((0x06, 0x08, got[0][2]))
    # Bad payload length, unknown CFG (VALSET on an M8), invalid dynModel: ACK-NAK.
    assert acks(b.cmd(0x06, 0x08, b"\x00" * 5), 0x08) == [0]
    assert acks(b.cmd(0x06, 0x8A, b"\x00\x01\x00\x00" + b"\x00" * 5), 0x8A) == [0]
    nav5 = struct.pack("<HBB", 0x0005, 1, 2) + bytes(32)
    assert acks(b.cmd(0x06, 0x24, nav5), 0x24) == [0]
    nav5 = struct.pack("<HBB", 0x0005, 8, 2) + bytes(32)
    assert acks(b.cmd(0x06, 0x24, nav5), 0x24) == [1]
    polled = next(f for f in b.cmd(0x06, 0x24) if f[:2] == (0x06, 0x24))[2]
    assert len(polled) == 36 and polled[2] == 8 and polled[3] == 2
    # CFG-MSG for a message the model cannot output: NAK; poll of a known one: 8-byte form.
    assert acks(b.cmd(0x06, 0x01, bytes((0x01, 0x02, 1))), 0x01) == [0]
    assert (0x06, 0x01, bytes((0xF0, 0x00, 1, 1, 1, 1, 1, 0))) in b.cmd(0x06, 0x01, b"\xf0\x00")
    # CFG-GNSS and CFG-CFG are accepted; MON-VER is not a CFG message: no ACK.
    assert acks(b.cmd(0x06, 0x3E, bytes((0, 0, 0xFF, 1, 0, 8, 16, 0, 1, 0, 1, 0))), 0x3E) == [1]
    assert acks(b.cmd(0x06, 0x09, bytes(12)), 0x09) == [1]
    assert not [f for f in b.cmd(0x0A, 0x04) if f[0] == 0x05]
    assert b.gps.config.current.meas_rate_ms == 200


def test_mon_ver_reply_identifies_an_m8_with_extensions():
    b = Bench(38400)
    got = [f for f in b.cmd(0x0A, 0x04) if f[:2] == (0x0A, 0x04)]
    assert len(got) == 1
    p = got[0][2]
    assert len(p) > 40 and (len(p) - 40) % 30 == 0
    assert p[30:40].rstrip(b"\0") == b"00080000"
    exts = [p[i:i + 30].rstrip(b"\0") for i in range(40, len(p), 30)]
    assert b"PROTVER=18.00" in exts and any(e.startswith(b"FWVER=") for e in exts)


def test_bad_checksum_ignored_and_garbage_resynchronised():
    b = Bench(9600)
    bad = bytearray(ubx(0x06, 0x08, struct.pack("<HHH", 100, 1, 0)))
    bad[-1] ^= 0xFF
    b.host.write(bytes(bad))
    assert not [f for f in frames(b.run(300 * MS)) if f[0] == 0x05]
    assert b.gps.config.current.meas_rate_ms == 1000
    # Garbage with a false sync in front of a good frame: the good frame is still found.
    b.host.write(b"\xb5\x62\x06\xff\xff" + b"junk\xb5" + ubx(0x06, 0x08,
                                                               struct.pack("<HHH", 500, 1, 0)))
    assert (0x05, 0x01, b"\x06\x08") in frames(b.run(300 * MS))
    assert b.gps.config.current.meas_rate_ms == 500


def test_baud_switch_after_cfg_prt_ack_at_old_rate():
    b = Bench(9600)
    b.run(1_200 * MS)  # NMEA flowing
    assert acks(b.cmd(0x06, 0x01, bytes((0x01, 0x07, 1)), 900 * MS), 0x01) == [1]
    b.host.reset_input_buffer()
    block = struct.pack("<BBHIIHHHH", 1, 0, 0, 0x8D0, 115200, 0x21, 0x01, 0, 0)
    b.host.write(ubx(0x06, 0x00, block))
    old = b.run(2 * S)
    # The ACK came at 9600 (after the NMEA already queued); what follows is at 115200.
    assert (0x05, 0x01, b"\x06\x00") in frames(old)
    assert b.gps.uart.config.baud == 115200
    assert b.host.framing_errors > 0
    assert not [f for f in frames(old[old.find(b"\xb5\x62\x05\x01") + 10:]) if f[1] == 0x07]
    b.baud(115200)
    b.run(10 * MS)
    good = frames(b.run(2 * S))
    assert [f for f in good if f[:2] == (0x01, 0x07)]
    assert not any(ln.startswith(b"$") for ln in b.host.read().split(b"\r\n"))


def decode_pvt(p: bytes) -> dict:
    """NAV-PVT by the reference's offsets."""
    u = struct.unpack_from
    return {"itow": u("<I", p, 0)[0], "year": u("<H", p, 4)[0], "month": p[6], "day": p[7], "hour": p[8],
                "valid": p[11], "fix": p[20], "flags": p[21], "num_sv": p[23], "lon": u("<i", p, 24)[0],
                "lat": u("<i", p, 28)[0], "height": u("<i", p, 32)[0], "hmsl": u("<i", p, 36)[0],
                "hacc": u("<I", p, 40)[0], "vacc": u("<I", p, 44)[0], "vn": u("<i", p, 48)[0],
                "ve": u("<i", p, 52)[0], "vd": u("<i", p, 56)[0], "gspeed": u("<i", p, 60)[0],
                "sacc": u("<I", p, 68)[0], "pdop": u("<H", p, 76)[0]}


def configure_pvt(b: Bench, meas_ms: int) -> None:
    b.ubx_only(115200)
    assert acks(b.cmd(0x06, 0x08, struct.pack("<HHH", meas_ms, 1, 0)), 0x08) == [1]
    assert acks(b.cmd(0x06, 0x01, bytes((0x01, 0x07, 1))), 0x01) == [1]


@pytest.mark.parametrize("meas_ms", [200, 100])
def test_nav_pvt_layout_and_rate(meas_ms):
    env = Environment(vel_ned_m_s=(5.0, -3.0, 0.5))
    b = Bench(38400, env=env)
    configure_pvt(b, meas_ms)
    b.run(1 * S)
    raw = [f[2] for f in frames(b.run(2 * S)) if f[:2] == (0x01, 0x07)]
    assert {len(p) for p in raw} == {92}
    pvts = [decode_pvt(p) for p in raw]
    assert len(pvts) == 2000 // meas_ms
    steps = {b2["itow"] - a["itow"] for a, b2 in itertools.pairwise(pvts)}
    assert steps == {meas_ms}
    for p in pvts:
        assert p["fix"] == 3 and p["flags"] & 1 and p["valid"] & 0x07 == 0x07
        assert (p["year"], p["month"], p["day"], p["hour"]) == (2024, 6, 1, 12)
        assert 10 <= p["num_sv"] <= 14
        dn = (p["lat"] * 1e-7 - env.lat_deg) * 111_320
        assert abs(dn) < 5 and abs(p["hmsl"] / 1000 - env.alt_m) < 10
        assert abs(p["height"] - p["hmsl"] - 47_400) < 1
        assert 500 < p["hacc"] < 3000 and p["vacc"] > p["hacc"]
        assert abs(p["vn"] - 5000) < 300 and abs(p["ve"] + 3000) < 300
        assert abs(p["vd"] - 500) < 400
        assert abs(p["gspeed"] - 5831) < 300


def test_no_fix_without_sky_and_fix_after_ttff():
    b = Bench(38400, ttff_s=2.0)
    configure_pvt(b, 200)
    # Within TTFF (2 s from power-on): no fix, flags 0.
    early = [decode_pvt(f[2]) for f in frames(b.run(1 * S)) if f[:2] == (0x01, 0x07)]
    assert early and all(p["fix"] == 0 and p["flags"] & 1 == 0 for p in early)
    late = [decode_pvt(f[2]) for f in frames(b.run(1_500 * MS)) if f[:2] == (0x01, 0x07)]
    assert late[-1]["fix"] == 3
    b.env.gps_available = False
    lost = [decode_pvt(f[2]) for f in frames(b.run(1 * S)) if f[:2] == (0x01, 0x07)]
    assert all(p["fix"] == 0 and p["flags"] & 1 == 0 and p["num_sv"] == 0 for p in lost)
    assert lost[-1]["hacc"] > lost[0]["hacc"]


def test_faults_jump_degrade_jam_absent():
    b = Bench(38400)
    configure_pvt(b, 200)
    assert acks(b.cmd(0x06, 0x01, bytes((0x0A, 0x09, 1))), 0x01) == [1]
    b.run(1 * S)
    ref = [decode_pvt(f[2]) for f in frames(b.run(S)) if f[:2] == (0x01, 0x07)][-1]
    b.gps.jump(100.0)
    jumped = [decode_pvt(f[2]) for f in frames(b.run(S)) if f[:2] == (0x01, 0x07)][-1]
    assert 95 < (jumped["lat"] - ref["lat"]) * 1e-7 * 111_320 < 105
    b.gps.jump(0.0)
    b.gps.degrade(10.0)
    worse = [decode_pvt(f[2]) for f in frames(b.run(S)) if f[:2] == (0x01, 0x07)][-1]
    assert worse["hacc"] > 8 * ref["hacc"] / 1.5
    b.gps.degrade(1.0)
    b.gps.jam(150)
    hw = [f[2] for f in frames(b.run(S)) if f[:2] == (0x0A, 0x09)][-1]
    assert len(hw) == 60 and hw[45] == 150 and struct.unpack_from("<H", hw, 16)[0] > 200
    b.gps.set_absent()
    b.run(10 * MS)
    assert b.run(2 * S) == b""
    assert b.cmd(0x0A, 0x04) == []


def test_tx_buffer_limits_output_to_what_the_baud_carries():
    b = Bench(9600)
    for msg in ((0x01, 0x30), (0x01, 0x35), (0x01, 0x07), (0x0A, 0x09)):
        b.cmd(0x06, 0x01, bytes((*msg, 1)), 100 * MS)
    b.cmd(0x06, 0x08, struct.pack("<HHH", 100, 1, 0), 100 * MS)
    b.host.reset_input_buffer()
    data = b.run(3 * S)
    assert len(data) <= 3 * 960 + 10
    assert b.gps.tx_dropped > 0
    assert b.host.framing_errors == 0


def test_same_seed_same_bytes():
    def record(seed: int) -> bytes:
        b = Bench(9600, seed=seed)
        return b.run(3 * S)
    assert record(7) == record(7)
    assert record(7) != record(8)


def test_host_at_wrong_baud_sees_framing_errors():
    b = Bench(9600)
    b.baud(38400)
    b.run(2 * S)
    assert b.host.take_errors() & FE
