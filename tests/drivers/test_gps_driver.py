"""GPS driver against the u-blox M8 model over a UART wire: detection from power-on,
configuration, sensor_gps at the configured rate, bad data, and faults seen and reported.
"""

from __future__ import annotations

import calendar
import itertools
import math

import pytest

from board.kernel import Kernel
from board.uart import Uart, UartConfig, UartWire
from firmware.drivers.device import BUS_TYPE_SERIAL, DeviceId
from firmware.drivers.gps import GpsDriver
from firmware.drivers.gps.gps import DEVTYPE_UBX_8
from firmware.platform import Platform
from firmware.platform.uorb import Subscription
from peripherals.errors import rng_for
from peripherals.physics import Environment
from peripherals.ublox import UbloxM8

MS = 1_000_000
S = 1_000_000_000


class Rig:
    """FMU UART4 (NuttX default 57600) wired to a receiver; the driver started at power-on."""

    def __init__(self, receiver_baud: int = 38400, ttff_s: float = 0.5, seed: int = 3) -> None:
        self.k = Kernel("fmu")
        self.p = Platform(self.k)
        self.env = Environment(vel_ned_m_s=(2.0, 1.0, 0.0))
        self.uart = Uart(self.k, "ttyS3", UartConfig(57600))
        self.gps = UbloxM8(self.k, self.env, rng_for(seed, "gps"), baud=receiver_baud,
                           ttff_s=ttff_s)
        UartWire(self.uart, self.gps.uart)
        self.drv = GpsDriver(self.p, self.uart)
        assert self.drv.start()
        self.sub = Subscription(self.p.orb, "sensor_gps")
        self.msgs: list = []

    def run(self, ns: int, step_ns: int = 50 * MS) -> list:
        """Run and collect every sensor_gps publication (polled often enough to see each)."""
        got = []
        end = self.k.now_ns + ns
        while self.k.now_ns < end:
            self.k.run(min(end, self.k.now_ns + step_ns))
            if self.sub.updated():
                got.append(self.sub.copy())
        self.msgs += got
        return got

    def dmesg(self) -> str:
        return self.p.dmesg_text()


def near(msg, env: Environment, tol_m: float) -> bool:
    dn = (msg.latitude_deg - env.lat_deg) * 111_320
    de = (msg.longitude_deg - env.lon_deg) * 111_320 * math.cos(math.radians(env.lat_deg))
    return math.hypot(dn, de) < tol_m and abs(msg.altitude_msl_m - env.alt_m) < 2 * tol_m


def test_from_power_on_at_factory_9600_detects_configures_and_publishes():
    r = Rig(receiver_baud=9600, ttff_s=2.0)
    r.run(7 * S)
    assert r.drv.configured and r.drv.board == 8 and r.drv.baud == 115200
    cfg = r.gps.config.current
    assert cfg.ports[1].baud == 115200 and cfg.ports[1].out_mask == 0x01  # UBX only
    assert cfg.meas_rate_ms == 200 and cfg.dyn_model == 8 and cfg.fix_mode == 2
    assert r.gps.naks == 1  # the CFG-VALSET an M8 must reject
    got = r.run(2 * S)
    assert 9 <= len(got) <= 11  # 5 Hz
    m = got[-1]
    assert m.fix_type == 3 and 10 <= m.satellites_used <= 14
    assert near(m, r.env, 5.0)
    assert 0.5 < m.eph < 3.0 and m.epv > m.eph and 0 < m.hdop < 2 and m.vdop > 0
    assert abs(m.vel_n_m_s - 2.0) < 0.3 and abs(m.vel_e_m_s - 1.0) < 0.3 and m.vel_ned_valid
    assert abs(m.cog_rad - math.atan2(1.0, 2.0)) < 0.2
    assert abs(m.altitude_ellipsoid_m - m.altitude_msl_m - 47.4) < 0.01
    did = DeviceId.decode(m.device_id)
    assert (did.bus_type, did.bus, did.devtype) == (BUS_TYPE_SERIAL, 3, DEVTYPE_UBX_8)
    utc0 = calendar.timegm((2024, 6, 1, 12, 0, 0)) * 1_000_000
    assert abs(m.time_utc_usec - utc0 - m.timestamp) < 100_000
    text = r.dmesg()
    assert "PROTVER=18.00" in text and "configured at 115200 baud, 5 Hz" in text
    assert "3D fix" in text


def test_receiver_saved_at_38400_is_configured_at_once():
    r = Rig(receiver_baud=38400)
    r.run(700 * MS)
    assert r.drv.configured and r.drv.perf_timeouts.events == 0
    r.run(500 * MS)
    assert r.drv.publish_count >= 2


def test_publications_spaced_by_the_configured_rate():
    r = Rig()
    r.run(1 * S)
    got = r.run(2 * S, step_ns=10 * MS)
    gaps = {b.timestamp - a.timestamp for a, b in itertools.pairwise(got)}
    assert all(abs(g - 200_000) < 2_000 for g in gaps)


def test_corrupt_frame_counted_and_parser_resynchronises():
    r = Rig()
    r.run(1_500 * MS)
    before = r.drv.publish_count
    frame = bytearray(b"\xb5\x62\x01\x07\x5c\x00" + bytes(92) + b"\x00\x00")
    r.uart.receive(r.k.now_ns, r.gps.uart.config, bytes(frame) + b"noise\xb5\xb5")
    r.run(1 * S)
    assert r.drv.perf_bad_checksum.events == 1
    assert r.drv.publish_count - before >= 4
    assert r.drv.configured


def test_loss_of_fix_and_return_reported():
    r = Rig()
    r.run(1_500 * MS)
    r.gps.lose_fix()
    got = r.run(1 * S)
    assert got and all(m.fix_type == 0 for m in got[1:])
    assert "fix lost" in r.dmesg()
    r.gps.lose_fix(False)
    got = r.run(2 * S)
    assert got[-1].fix_type == 3
    assert r.dmesg().count("3D fix") == 2


def test_position_jump_reported():
    r = Rig()
    r.run(1_500 * MS)
    r.gps.jump(40.0, -20.0)
    got = r.run(500 * MS)
    assert "position jump of" in r.dmesg()
    assert not near(got[-1], r.env, 30.0)


def test_jamming_and_degraded_accuracy_reported():
    r = Rig()
    r.run(1_500 * MS)
    r.gps.jam(150)
    got = r.run(1 * S)
    assert got[-1].jamming_indicator == 150 and got[-1].noise_per_ms > 200
    assert "jamming detected (indicator 150)" in r.dmesg()
    r.gps.jam(0)
    r.gps.degrade(8.0)
    got = r.run(1 * S)
    assert got[-1].eph > 5.0
    assert "jamming over" in r.dmesg() and "accuracy degraded" in r.dmesg()


def test_absent_receiver_detected_then_reconfigured_when_back():
    r = Rig()
    r.run(1_500 * MS)
    count = r.drv.publish_count
    r.gps.set_absent()
    r.run(1_500 * MS)
    assert not r.drv.configured
    assert r.drv.publish_count == count
    assert "no data for 1000 ms, reconfiguring" in r.dmesg()
    assert r.drv.perf_timeouts.events >= 1
    r.gps.set_absent(False)
    # Back at 115200: the scan passes 38400, 57600 and 9600 (VALSET + CFG-PRT timeouts each)
    # before it finds the receiver again.
    r.run(9 * S)
    assert r.drv.configured and r.drv.baud == 115200
    assert r.drv.publish_count > count + 5


@pytest.mark.parametrize("seed", [5])
def test_same_seed_same_publications(seed):
    def trace() -> list[tuple]:
        r = Rig(seed=seed)
        return [(m.timestamp, m.lat, m.lon, m.alt, m.eph) for m in r.run(2 * S)]
    assert trace() == trace()
