"""Estimator accuracy: the FMU's own estimate (from its ULog) against the world's truth.

The FMU's clock is the orchestrator's (virtual time, microseconds), so a logged
``vehicle_attitude`` sample can be compared with the truth recorded at the same virtual time:
no transport delay distorts the comparison, unlike an estimate seen through telemetry. Truth is
linearly interpolated between its samples (the flight records it every 50 ms; the attitude of a
multicopter changes little in that time). Angles wrap.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from typing import Sequence

__all__ = ["TruthSample", "Accuracy", "estimator_accuracy"]


@dataclass(frozen=True)
class TruthSample:
    t_s: float
    lat_deg: float
    lon_deg: float
    alt_m: float
    euler_rad: tuple[float, float, float]


@dataclass(frozen=True)
class Accuracy:
    attitude_rms_deg: float   # largest of roll/pitch/yaw error, rms over samples
    attitude_max_deg: float
    tilt_max_deg: float       # roll and pitch only
    position_rms_m: float     # 3-D distance
    position_max_m: float
    samples: int


def _wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


def _euler(q: Sequence[float]) -> tuple[float, float, float]:
    w, x, y, z = q
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return roll, pitch, yaw


def _interp(truth: list[TruthSample], times: list[float], t: float) -> TruthSample | None:
    i = bisect.bisect_left(times, t)
    if i == 0 or i >= len(times):
        return None
    a, b = truth[i - 1], truth[i]
    f = (t - a.t_s) / (b.t_s - a.t_s) if b.t_s > a.t_s else 0.0
    eul = tuple(ea + f * _wrap(eb - ea) for ea, eb in zip(a.euler_rad, b.euler_rad))
    return TruthSample(t, a.lat_deg + f * (b.lat_deg - a.lat_deg),
                       a.lon_deg + f * (b.lon_deg - a.lon_deg),
                       a.alt_m + f * (b.alt_m - a.alt_m), eul)  # type: ignore[arg-type]


M_PER_DEG_LAT = 111_132.954


def estimator_accuracy(ulog_path: str, truth: list[TruthSample], t_from_s: float,
                       t_to_s: float) -> Accuracy:
    """Compare ``vehicle_attitude`` and ``vehicle_local_position`` of the log with the truth
    between ``t_from_s`` and ``t_to_s`` (virtual seconds).

    The estimate is turned into a geodetic position through its own reference point
    (``ref_lat``/``ref_lon``/``ref_alt``) and compared with the truth's latitude, longitude and
    altitude, so a GPS bias the estimator cannot know counts as error, as it should.
    """
    import pyulog

    log = pyulog.ULog(ulog_path, ["vehicle_attitude", "vehicle_local_position"])
    times = [s.t_s for s in truth]
    att = log.get_dataset("vehicle_attitude").data
    att_err: list[float] = []
    tilt: list[float] = []
    for i, t_us in enumerate(att["timestamp"]):
        t = t_us * 1e-6
        if not t_from_s <= t <= t_to_s:
            continue
        ref = _interp(truth, times, t)
        if ref is None:
            continue
        est = _euler([att[f"q[{k}]"][i] for k in range(4)])
        errs = [abs(_wrap(e - r)) for e, r in zip(est, ref.euler_rad)]
        att_err.append(max(errs))
        tilt.append(max(errs[0], errs[1]))
    lpos = log.get_dataset("vehicle_local_position").data
    pos_err: list[float] = []
    for i, t_us in enumerate(lpos["timestamp"]):
        t = t_us * 1e-6
        if not t_from_s <= t <= t_to_s or not lpos["xy_valid"][i]:
            continue
        ref = _interp(truth, times, t)
        if ref is None:
            continue
        m_per_deg_lon = M_PER_DEG_LAT * math.cos(math.radians(ref.lat_deg))
        dn = (float(lpos["ref_lat"][i]) - ref.lat_deg) * M_PER_DEG_LAT + float(lpos["x"][i])
        de = (float(lpos["ref_lon"][i]) - ref.lon_deg) * m_per_deg_lon + float(lpos["y"][i])
        dd = (float(lpos["ref_alt"][i]) - float(lpos["z"][i])) - ref.alt_m
        pos_err.append(math.sqrt(dn * dn + de * de + dd * dd))
    if not att_err or not pos_err:
        raise ValueError(f"{ulog_path}: no estimator samples between {t_from_s} and {t_to_s} s")
    return Accuracy(
        attitude_rms_deg=math.degrees(math.sqrt(sum(e * e for e in att_err) / len(att_err))),
        attitude_max_deg=math.degrees(max(att_err)),
        tilt_max_deg=math.degrees(max(tilt)),
        position_rms_m=math.sqrt(sum(e * e for e in pos_err) / len(pos_err)),
        position_max_m=max(pos_err),
        samples=len(att_err))
