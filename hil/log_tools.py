"""``hil log info FILE`` and ``hil log plot FILE [TOPIC...]``: look into ULog files.

Both read with pyulog, so they work on files from this emulator and from real PX4 boards alike
(the reader must survive odd real logs: version 0 files, appended crash dumps, topics stamped
before logging began). Plots use matplotlib's Agg backend (files only, no display).
"""

from __future__ import annotations

import math
import os
import struct
import sys
from pathlib import Path
from typing import Any, TextIO

__all__ = ["STANDARD_PLOTS", "info_main", "info_text", "plot_main"]

_LEVELS = {0: "EMERG", 1: "ALERT", 2: "CRIT", 3: "ERROR", 4: "WARN", 5: "NOTICE", 6: "INFO",
           7: "DEBUG"}
MAX_LOGGED_LINES = 100


def _hms(us: float) -> str:
    s = int(us // 1_000_000) if us > 0 else 0
    return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}"


def _load(path: str | os.PathLike, err: TextIO) -> Any:
    """The pyulog ULog of ``path``, or None (after saying why)."""
    p = Path(path)
    try:
        with open(p, "rb") as f:
            head = f.read(16)
    except OSError as exc:
        print(f"hil log: cannot read {p}: {exc.strerror or exc}", file=err)
        return None
    if len(head) < 16 or head[:7] != b"ULog\x01\x12\x35":
        print(f"hil log: {p} is not a ULog file (bad header)", file=err)
        return None
    try:
        from pyulog import ULog
    except ImportError:
        print("hil log: pyulog is not installed (pip install pyulog)", file=err)
        return None
    try:
        ulog = ULog(str(p))
    except Exception as exc:  # noqa: BLE001 - any reader failure is reported, not raised
        print(f"hil log: cannot parse {p}: {type(exc).__name__}: {exc}", file=err)
        return None
    ulog._hil_file_version = head[7]          # pyulog keeps it private
    ulog._hil_header_us = struct.unpack("<Q", head[8:16])[0]
    return ulog


def _field_size(type_str: str) -> int:
    from pyulog import ULog
    return ULog.get_field_size(type_str)


def info_text(ulog: Any, name: str = "") -> str:
    """The summary ``hil log info`` prints (in the spirit of pyulog's ``ulog_info -v``)."""
    out: list[str] = []
    if name:
        out.append(f"File: {name}")
    version = getattr(ulog, "_hil_file_version", None)
    flags = []
    if ulog.has_data_appended:
        offs = [o for o in getattr(ulog, "_appended_offsets", []) if o > 0]
        flags.append(f"data appended ({len(offs)} offsets: {', '.join(map(str, offs))})")
    if ulog.has_default_parameters:
        flags.append("default parameters")
    out.append(f"ULog format version: {version}" + (f", flags: {'; '.join(flags)}" if flags
                                                    else ""))
    start = ulog.start_timestamp
    out.append(f"Logging start time: {_hms(start)}, duration: "
               f"{_hms(ulog.last_timestamp - start)}")
    if ulog.file_corruption:
        out.append("File corruption detected (the reader skipped damaged data)")
    drops = [d.duration for d in ulog.dropouts]
    if drops:
        out.append(f"Dropouts: count: {len(drops)}, total duration: {sum(drops) / 1000:.1f} s, "
                   f"max: {max(drops)} ms, mean: {sum(drops) // len(drops)} ms")
    else:
        out.append("No Dropouts")
    out.append("Info Messages:")
    for key in sorted(ulog.msg_info_dict):
        value = ulog.msg_info_dict[key]
        if isinstance(value, (bytes, bytearray)):
            value = f"<{len(value)} bytes>"
        elif key.startswith("ver_") and key.endswith("release") and isinstance(value, int):
            value = f"0x{value:08x}"
        out.append(f" {key}: {value}")
    multi = ulog.msg_info_multiple_dict
    if multi:
        out.append("Info Multiple Messages:")
        for key in sorted(multi):
            out.append(f" {key}: {len(multi[key])} set(s)")
    changed = ulog.changed_parameters
    out.append(f"Parameters: {len(ulog.initial_parameters)} "
               f"({len(changed)} change(s) during the log)")
    for t, pname, value in changed:
        out.append(f" {_hms(t)} {pname} = {value}")
    out.append("")
    out.append(f"{'Name (multi id, message size in bytes)':<42}{'number of data points':>22}"
               f"{'total bytes':>13}")
    for d in sorted(ulog.data_list, key=lambda d: (d.name, d.multi_id)):
        size = sum(_field_size(f.type_str) for f in d.field_data)
        n = len(d.data["timestamp"])
        out.append(f" {d.name + f' ({d.multi_id}, {size})':<41}{n:>22}{n * size:>13}")
    out.append("")
    msgs = list(ulog.logged_messages)
    for tag_msgs in ulog.logged_messages_tagged.values():
        msgs.extend(tag_msgs)
    msgs.sort(key=lambda m: m.timestamp)
    out.append(f"Logged messages: {len(msgs)}")
    for m in msgs[:MAX_LOGGED_LINES]:
        level = m.log_level - 0x30 if 0x30 <= m.log_level <= 0x37 else m.log_level
        out.append(f" {_hms(m.timestamp)} {_LEVELS.get(level, str(level)):<6} {m.message}")
    if len(msgs) > MAX_LOGGED_LINES:
        out.append(f" ... {len(msgs) - MAX_LOGGED_LINES} more")
    return "\n".join(out)


def info_main(path: str | os.PathLike, out: TextIO | None = None,
              err: TextIO | None = None) -> int:
    """``hil log info FILE``: print a summary of a ULog file. 0 on success, 1 otherwise."""
    out = out or sys.stdout
    err = err or sys.stderr
    ulog = _load(path, err)
    if ulog is None:
        return 1
    print(info_text(ulog, Path(path).name), file=out)
    return 0


# -- plots ------------------------------------------------------------------------------------

def _series(ulog: Any, topic: str) -> list[Any]:
    return sorted((d for d in ulog.data_list if d.name == topic), key=lambda d: d.multi_id)


def _time_s(ulog: Any, d: Any) -> Any:
    return (d.data["timestamp"].astype("float64") - ulog.start_timestamp) / 1e6


def _euler_deg(q0: Any, q1: Any, q2: Any, q3: Any) -> tuple[Any, Any, Any]:
    """Roll, pitch, yaw (3-2-1 Tait-Bryan, degrees) from a quaternion w, x, y, z."""
    import numpy as np
    roll = np.arctan2(2 * (q0 * q1 + q2 * q3), 1 - 2 * (q1 * q1 + q2 * q2))
    pitch = np.arcsin(np.clip(2 * (q0 * q2 - q3 * q1), -1.0, 1.0))
    yaw = np.arctan2(2 * (q0 * q3 + q1 * q2), 1 - 2 * (q2 * q2 + q3 * q3))
    return np.degrees(roll), np.degrees(pitch), np.degrees(yaw)


def _plot_attitude(ulog: Any, fig: Any) -> bool:
    series = _series(ulog, "vehicle_attitude")
    if not series:
        return False
    axes = fig.subplots(3, 1, sharex=True)
    for d in series:
        t = _time_s(ulog, d)
        angles = _euler_deg(*(d.data[f"q[{i}]"].astype("float64") for i in range(4)))
        for ax, a, label in zip(axes, angles, ("roll", "pitch", "yaw")):
            ax.plot(t, a, label=f"{label} [{d.multi_id}]")
            ax.set_ylabel(f"{label} (deg)")
    axes[-1].set_xlabel("time (s)")
    fig.suptitle("attitude (vehicle_attitude)")
    return True


def _xyz_fields(d: Any, names: list[tuple[str, str, str]]) -> tuple[str, str, str] | None:
    for triple in names:
        if all(n in d.data for n in triple):
            return triple
    return None


def _plot_triples(ulog: Any, fig: Any, candidates: list[tuple[str, list[tuple[str, str, str]]]],
                  title: str, unit: str, scale: float = 1.0) -> bool:
    for topic, names in candidates:
        series = _series(ulog, topic)
        found = [(d, _xyz_fields(d, names)) for d in series]
        found = [(d, f) for d, f in found if f]
        if not found:
            continue
        axes = fig.subplots(3, 1, sharex=True)
        for d, fields in found:
            t = _time_s(ulog, d)
            for ax, fname in zip(axes, fields):
                ax.plot(t, d.data[fname].astype("float64") * scale,
                        label=f"{fname} [{d.multi_id}]")
                ax.set_ylabel(unit)
        for ax in axes:
            ax.legend(loc="upper right", fontsize="small")
        axes[-1].set_xlabel("time (s)")
        fig.suptitle(f"{title} ({topic})")
        return True
    return False


def _plot_rates(ulog: Any, fig: Any) -> bool:
    return _plot_triples(ulog, fig, [
        ("vehicle_angular_velocity", [("xyz[0]", "xyz[1]", "xyz[2]")]),
        ("sensor_gyro", [("x", "y", "z")]),
        ("sensor_combined", [("gyro_rad[0]", "gyro_rad[1]", "gyro_rad[2]")]),
    ], "angular rates", "deg/s", 180.0 / math.pi)


def _plot_position(ulog: Any, fig: Any) -> bool:
    return _plot_triples(ulog, fig, [("vehicle_local_position", [("x", "y", "z")])],
                         "local position NED", "m")


def _plot_fields(ulog: Any, ax: Any, d: Any, skip_constant: bool = False,
                 max_fields: int = 16) -> int:
    t = _time_s(ulog, d)
    n = 0
    for f in d.field_data:
        name = f.field_name
        if name.startswith(("timestamp", "_padding")) or f.type_str == "char":
            continue
        v = d.data[name].astype("float64")
        if skip_constant and len(v) and (v == v[0]).all():
            continue
        if n >= max_fields:
            break
        ax.plot(t, v, label=f"{name} [{d.multi_id}]" if d.multi_id else name)
        n += 1
    return n


def _plot_topics(ulog: Any, fig: Any, topics: list[str], title: str,
                 skip_constant: bool = True) -> bool:
    present = [(topic, _series(ulog, topic)) for topic in topics]
    present = [(topic, s) for topic, s in present if s]
    if not present:
        return False
    axes = fig.subplots(len(present), 1, sharex=True, squeeze=False)[:, 0]
    for ax, (topic, series) in zip(axes, present):
        for d in series:
            _plot_fields(ulog, ax, d, skip_constant=skip_constant)
        ax.set_title(topic, fontsize="small")
        if ax.get_lines():
            ax.legend(loc="upper right", fontsize="x-small", ncol=2)
    axes[-1].set_xlabel("time (s)")
    fig.suptitle(title)
    return True


def _plot_setpoints(ulog: Any, fig: Any) -> bool:
    return _plot_topics(ulog, fig, ["vehicle_attitude_setpoint", "vehicle_rates_setpoint",
                                    "vehicle_local_position_setpoint"], "setpoints")


def _plot_actuators(ulog: Any, fig: Any) -> bool:
    return _plot_topics(ulog, fig, ["actuator_controls_0", "actuator_outputs"],
                        "actuator controls and outputs")


#: name -> (what it needs, plot function)
STANDARD_PLOTS = {
    "attitude": ("vehicle_attitude", _plot_attitude),
    "rates": ("vehicle_angular_velocity, sensor_gyro or sensor_combined", _plot_rates),
    "position": ("vehicle_local_position", _plot_position),
    "setpoints": ("vehicle_*_setpoint", _plot_setpoints),
    "actuators": ("actuator_controls_0 or actuator_outputs", _plot_actuators),
}


def plot_main(path: str | os.PathLike, topics: list[str] | None = None,
              out_dir: str | os.PathLike | None = None, out: TextIO | None = None,
              err: TextIO | None = None) -> int:
    """``hil log plot FILE [TOPIC...]``: write PNG plots next to the log (or into ``out_dir``).

    The standard plots (attitude, rates, position, setpoints, actuators) are drawn when their
    topics are in the log; each named topic gets a plot of all its fields. Missing topics are
    skipped with a note. Returns 0 when at least one plot was written, 1 otherwise.
    """
    out = out or sys.stdout
    err = err or sys.stderr
    ulog = _load(path, err)
    if ulog is None:
        return 1
    try:
        import matplotlib
        matplotlib.use("Agg")
        from matplotlib.figure import Figure
    except ImportError:
        print("hil log plot: matplotlib is not installed (pip install matplotlib)", file=err)
        return 1
    dest = Path(out_dir) if out_dir is not None else Path(path).resolve().parent
    dest.mkdir(parents=True, exist_ok=True)
    stem = Path(path).stem
    written: list[Path] = []

    def save(fig: Any, name: str) -> None:
        target = dest / f"{stem}_{name}.png"
        fig.savefig(target, dpi=90)
        written.append(target)
        print(f"wrote {target}", file=out)

    for name, (needs, fn) in STANDARD_PLOTS.items():
        fig = Figure(figsize=(10, 7))
        if fn(ulog, fig):
            save(fig, name)
        else:
            print(f"note: no {name} plot (needs {needs})", file=out)
    known = {d.name for d in ulog.data_list}
    for topic in topics or []:
        if topic not in known:
            print(f"note: topic {topic} is not in the log, skipped", file=out)
            continue
        fig = Figure(figsize=(10, 6))
        _plot_topics(ulog, fig, [topic], topic, skip_constant=False)
        save(fig, topic)
    if not written:
        print("hil log plot: nothing to plot", file=err)
        return 1
    return 0
