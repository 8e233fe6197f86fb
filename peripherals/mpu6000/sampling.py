"""The MPU-6000 signal chain, computed for a batch of samples at once.

Per sample: truth (board frame, SI) -> mounting rotation -> error model (scale, cross-axis,
bias, drift; evaluated once per batch) -> self-test shift -> DLPF -> white noise -> counts at
the configured full scale -> clamp to the 16-bit rails.

The DLPF is a first-order low-pass at the table's bandwidth, run at the gyro's internal rate
(8 kHz for DLPF_CFG 0/7, else 1 kHz) and at 1 kHz for the accelerometer. The input is constant
within a batch, so the filter has a closed form (``y_k = x + (y_0 - x) a^k``): skipped samples
cost nothing and the result is exact. The table's
group delay is not reproduced (a first-order filter delays by 1/(2 pi f_c)). Noise is white
at the datasheet density over the filter's noise bandwidth (pi/2 f_c, capped at Nyquist).

The accelerometer runs at 1 kHz: above that sample rate the same accelerometer reading is
repeated in the data registers and the FIFO (eight times at 8 kHz), and PX4 checks for it.
"""

from __future__ import annotations

import math
import struct
from typing import Final

import numpy as np

from peripherals.errors import ImuErrorModel
from peripherals.faults import FaultState
from peripherals.mpu6000.registers import (
    ACCEL_CONFIG_XA_ST,
    ACCEL_LSB_PER_G,
    DEG,
    DLPF_TABLE,
    FIFO_EN_ACCEL_FIFO_EN,
    FIFO_EN_TEMP_FIFO_EN,
    FIFO_EN_XG_FIFO_EN,
    FIFO_EN_YG_FIFO_EN,
    FIFO_EN_ZG_FIFO_EN,
    GYRO_CONFIG_XG_ST,
    GYRO_LSB_PER_DPS,
    SELF_TEST_BITS,
)
from peripherals.mpu6000.rotation import Matrix3
from peripherals.physics import Environment
from common.units import G0_M_S2

__all__ = ["SampleEngine"]

ACCEL_PERIOD_NS: Final = 1_000_000
NOISE_BLOCK: Final = 8192
_PACK7: Final = struct.Struct(">7h").pack


class SampleEngine:
    """Filter state and scaling of one chip; :meth:`produce` turns elapsed time into samples."""

    def __init__(self, rng: np.random.Generator, rotation: Matrix3 | None,
                 gyro_err: ImuErrorModel, accel_err: ImuErrorModel,
                 self_test: tuple[tuple[float, ...], tuple[float, ...]], rev_c: bool) -> None:
        self.rng = rng
        self.rotation = rotation
        self.gyro_err = gyro_err
        self.accel_err = accel_err
        self._st_accel_full = tuple(v * G0_M_S2 for v in self_test[0])
        self._st_gyro_full = tuple(v * DEG for v in self_test[1])
        self._noise: list[float] = []
        self._npos = 0
        self.rev_c = rev_c
        self._cols_cache: dict[int, list[int]] = {}
        self.reset_filters()
        self._acc_origin = 0
        self._acc_tick = -1
        self._acc_counts = (0, 0, 0)
        self._temp_counts = 0
        self._last: tuple[int, ...] | None = None
        self.configure(0, 0, 0, 0, 0, 0, 0)

    def reset_filters(self, gyro: bool = True, accel: bool = True) -> None:
        """Signal path reset: the filters restart from the next input (no settling tail)."""
        if gyro:
            self._g_state: tuple[float, float, float] | None = None
        if accel:
            self._a_state: tuple[float, float, float] | None = None

    def wake(self, t_ns: int) -> None:
        """Sampling starts at ``t_ns`` (out of sleep or reset): accel ticks are phased to it."""
        self.reset_filters()
        self._acc_origin = t_ns
        self._acc_tick = -1

    def configure(self, dlpf: int, div: int, fs_sel: int, afs_sel: int, gyro_st: int,
                  accel_st: int, pwr_mgmt_2: int) -> None:
        """Derive the per-sample constants from the configuration registers."""
        bw_a, bw_g, rate_g = DLPF_TABLE[dlpf]
        self._a_g = math.exp(-2 * math.pi * bw_g / rate_g) ** (1 + div)
        self._a_a = math.exp(-2 * math.pi * bw_a / 1000.0)
        self._sigma_g = math.sqrt(min(rate_g / 2, bw_g * math.pi / 2))
        self._sigma_a = math.sqrt(min(500.0, bw_a * math.pi / 2))
        self._lsb_g = GYRO_LSB_PER_DPS[fs_sel] / DEG
        self._lsb_a = ACCEL_LSB_PER_G[afs_sel] / G0_M_S2 * (2.0 if self.rev_c else 1.0)
        # Self-test: the trim-derived response is added on the axes whose ST bit is set.
        self._g_on = bool(gyro_st & SELF_TEST_BITS)
        self._st_gyro = tuple(v if gyro_st & (GYRO_CONFIG_XG_ST >> i) else 0.0
                              for i, v in enumerate(self._st_gyro_full))
        self._a_on = bool(accel_st & SELF_TEST_BITS)
        self._st_accel = tuple(v if accel_st & (ACCEL_CONFIG_XA_ST >> i) else 0.0
                               for i, v in enumerate(self._st_accel_full))
        standby = [(pwr_mgmt_2 >> b) & 1 for b in (5, 4, 3)] + [0] + \
            [(pwr_mgmt_2 >> b) & 1 for b in (2, 1, 0)]
        self._standby = frozenset(i for i, s in enumerate(standby) if s)

    def columns(self, fifo_en: int) -> list[int]:
        """Sample-row columns written to the FIFO per FIFO_EN, in the datasheet's order."""
        cols = self._cols_cache.get(fifo_en)
        if cols is None:
            cols = []
            if fifo_en & FIFO_EN_ACCEL_FIFO_EN:
                cols += [0, 1, 2]
            for bit, col in ((FIFO_EN_TEMP_FIFO_EN, 3), (FIFO_EN_XG_FIFO_EN, 4),
                             (FIFO_EN_YG_FIFO_EN, 5), (FIFO_EN_ZG_FIFO_EN, 6)):
                if fifo_en & bit:
                    cols.append(col)
            self._cols_cache[fifo_en] = cols
        return cols

    def record_bytes(self, fifo_en: int) -> int:
        return 2 * len(self.columns(fifo_en))

    def _input(self, err: ImuErrorModel, truth: tuple[float, float, float], t_ns: int,
               temp_c: float, extra: tuple[float, float, float]) -> tuple[float, float, float]:
        r = self.rotation
        if r is not None:
            x, y, z = truth
            truth = (r[0][0] * x + r[0][1] * y + r[0][2] * z,
                     r[1][0] * x + r[1][1] * y + r[1][2] * z,
                     r[2][0] * x + r[2][1] * y + r[2][2] * z)
        x, y, z = err.apply(t_ns, truth, 0.0, temp_c)
        # float(): the drift term comes back as numpy scalars, 20x slower in the sample loop.
        return float(x) + extra[0], float(y) + extra[1], float(z) + extra[2]

    def _normals(self, n: int) -> list[float]:
        """At least ``n`` fresh N(0, 1) draws: one numpy call per few thousand samples."""
        if self._npos + n > len(self._noise):
            self._noise = self.rng.standard_normal(max(NOISE_BLOCK, n)).tolist()
            self._npos = 0
        return self._noise

    def produce(self, env: Environment, t0: int, period: int, k1: int, n: int, fifo_en: int,
                fifo_size: int, faults: FaultState, bias_step_sensor: str,
                temp_enabled: bool) -> tuple[bytes, bytes]:
        """Samples ``k1 .. k1+n-1`` (at ``t0 + k*period``): the last one's 14 data-register
        bytes, and the FIFO bytes of the records that can still be seen.

        Pure Python on purpose: a batch is typically 8 samples, where numpy's per-call cost
        dominates; the batch length is bounded by the FIFO size whatever the elapsed time.
        This runs 1000 times per virtual second with PX4's driver, so it avoids building the
        7-column rows unless a fault or standby axis needs them and packs the FIFO records with
        a cached struct; the arithmetic (and so every count) is the one described above, in
        the same order of operations and of random draws.
        """
        cols = self._cols_cache.get(fifo_en)
        if cols is None:
            cols = self.columns(fifo_en)
        m = min(n, fifo_size // (2 * len(cols)) + 2) if cols else 1
        skip = n - m
        k_first = k1 + skip
        t_last = t0 + (k1 + n - 1) * period
        temp_c = env.board_temperature_c
        step = faults.bias_step
        noise = self._normals(6 * m)
        pos = self._npos
        self._npos = pos + 6 * m

        # Gyroscope: every sample is new.
        gx, gy, gz = self._input(self.gyro_err, env.gyro_rad_s, t_last, temp_c,
                                 step if bias_step_sensor != "accel" else _ZERO3)
        if self._g_on:
            st = self._st_gyro
            gx, gy, gz = gx + st[0], gy + st[1], gz + st[2]
        s = self._g_state or (gx, gy, gz)
        dx, dy, dz = s[0] - gx, s[1] - gy, s[2] - gz
        a = self._a_g
        p = a ** skip if a > 0.0 else 0.0
        lg = self._lsb_g
        gerr = self.gyro_err
        sg = gerr.p.noise_density * self._sigma_g * gerr.noise_scale * lg
        extra = faults.noise  # a noise burst (FaultState.noise): sigma in SI per sample
        if extra:
            sg = math.hypot(sg, extra.get("gyro", 0.0) * lg)

        # Accelerometer: a new reading per 1 ms tick, repeated in between. Its draws follow
        # the gyro's 3 * m in the block (computed first here, drawn in that order as always).
        apos = pos + 3 * m
        origin = self._acc_origin
        t_prev = self._acc_tick
        counts = self._acc_counts
        xa = None
        accel: list[tuple[int, int, int]] = []
        # Walk the batch by runs of samples that share a 1 ms tick (typically two runs of a
        # batch of eight), not sample by sample: same readings, far fewer steps.
        t_start = t0 + k_first * period - origin
        j = 0
        while j < m:
            tick = (t_start + j * period) // ACCEL_PERIOD_NS
            j_end = -(-((tick + 1) * ACCEL_PERIOD_NS - t_start) // period)  # first of next tick
            if j_end > m:
                j_end = m
            if tick != t_prev:
                if xa is None:
                    xa = self._input(self.accel_err, env.accel_m_s2, t_last, temp_c,
                                     step if bias_step_sensor != "gyro" else _ZERO3)
                    if self._a_on:
                        st = self._st_accel
                        xa = (xa[0] + st[0], xa[1] + st[1], xa[2] + st[2])
                    sa = self._a_state or xa
                    la = self._lsb_a
                    aerr = self.accel_err
                    na = aerr.p.noise_density * self._sigma_a * aerr.noise_scale * la
                    if extra:
                        na = math.hypot(na, extra.get("accel", 0.0) * la)
                pa = self._a_a ** (tick - t_prev) if tick > t_prev else 1.0
                sa = (xa[0] + pa * (sa[0] - xa[0]), xa[1] + pa * (sa[1] - xa[1]),
                      xa[2] + pa * (sa[2] - xa[2]))
                counts = (_clamp(sa[0] * la + na * noise[apos]),
                          _clamp(sa[1] * la + na * noise[apos + 1]),
                          _clamp(sa[2] * la + na * noise[apos + 2]))
                apos += 3
                t_prev = tick
            accel += [counts] * (j_end - j)
            j = j_end
        if xa is not None:
            self._a_state = sa
        self._acc_tick = t_prev
        self._acc_counts = counts
        if temp_enabled:
            self._temp_counts = _clamp((temp_c - 36.53) * 340.0)
        tc = self._temp_counts
        rnd = round

        if cols == _ACCEL_GYRO_COLS and not (self._standby or faults.frozen
                                              or faults.random_data or faults.saturate):
            # PX4's configuration: the FIFO records (accel then gyro) are built in the gyro
            # loop itself, one flat list, one pack. Same arithmetic as the general path.
            flat: list[int] = []
            extend = flat.extend
            gyro_last = (0, 0, 0)
            for j in range(m):
                p *= a
                extend(accel[j])
                gyro_last = (rnd((gx + p * dx) * lg + sg * noise[pos]),
                             rnd((gy + p * dy) * lg + sg * noise[pos + 1]),
                             rnd((gz + p * dz) * lg + sg * noise[pos + 2]))
                extend(gyro_last)
                pos += 3
            self._g_state = (gx + p * dx, gy + p * dy, gz + p * dz)
            if max(flat) > 32767 or min(flat) < -32768:
                flat = [_clamp(v) for v in flat]
                gyro_last = (flat[-3], flat[-2], flat[-1])
            last = accel[-1] + (tc,) + gyro_last
            self._last = last
            return _PACK7(*last), _packer(len(flat))(*flat)

        # Gyroscope: every sample is new.
        gyro: list[tuple[int, int, int]] = []
        append = gyro.append
        for _ in range(m):
            p *= a
            append((rnd((gx + p * dx) * lg + sg * noise[pos]),
                    rnd((gy + p * dy) * lg + sg * noise[pos + 1]),
                    rnd((gz + p * dz) * lg + sg * noise[pos + 2])))
            pos += 3
        if max(map(max, gyro)) > 32767 or min(map(min, gyro)) < -32768:
            gyro = [(_clamp(g[0]), _clamp(g[1]), _clamp(g[2])) for g in gyro]
        self._g_state = (gx + p * dx, gy + p * dy, gz + p * dz)

        if self._standby or faults.frozen or faults.random_data or faults.saturate:
            rows: list[tuple[int, ...]] = [ac + (tc,) + g for ac, g in zip(accel, gyro, strict=True)]
            rows = self._faults(rows, faults)
            self._last = rows[-1]
            regs = _PACK7(*rows[-1])
            if not cols:
                return regs, b""
            flat = [row[c] for row in rows for c in cols]
            return regs, _packer(len(flat))(*flat)
        last = accel[-1] + (tc,) + gyro[-1]
        self._last = last
        regs = _PACK7(*last)
        if not cols:
            return regs, b""
        rows = [ac + (tc,) + g for ac, g in zip(accel, gyro)]
        flat = [row[c] for row in rows for c in cols]
        return regs, _packer(len(flat))(*flat)

    def _faults(self, rows: list[tuple[int, ...]], faults: FaultState) -> list[tuple[int, ...]]:
        """Standby axes read 0; then frozen / random / saturated output replaces the data."""
        if self._standby:
            sb = self._standby
            rows = [tuple(0 if i in sb else v for i, v in enumerate(r)) for r in rows]
        if faults.frozen and self._last is not None:
            rows = [self._last] * len(rows)
        elif faults.random_data:
            rnd = self.rng.integers(-32768, 32768, (len(rows), 7)).tolist()
            rows = [tuple(r) for r in rnd]
        if faults.saturate:
            rows = [(32767, 32767, 32767, r[3], 32767, 32767, 32767) for r in rows]
        return rows


_ZERO3 = (0.0, 0.0, 0.0)
_ACCEL_GYRO_COLS: Final = [0, 1, 2, 4, 5, 6]
_PACKERS: Final[dict[int, object]] = {}


def _packer(n: int):  # noqa: ANN202 - a bound Struct.pack
    """``struct.Struct(f">{n}h").pack``, cached per length (FIFO reads are always 48 values)."""
    pack = _PACKERS.get(n)
    if pack is None:
        pack = _PACKERS[n] = struct.Struct(f">{n}h").pack
    return pack


def _clamp(v: float) -> int:
    """Round to the nearest count and clamp to the 16-bit rails, as the ADC output saturates."""
    if v >= 32767.0:
        return 32767
    if v <= -32768.0:
        return -32768
    return round(v)
