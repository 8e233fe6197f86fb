"""The companion computer in the emulated system: its board, its wire, the FMU's settings.

:func:`add_companion` is what :func:`hil.system.build_system` does for
``SystemConfig.companion`` (and ``companion_att``, ``ros``, which imply it): a third board
(``companion.board:CompanionBoard``) on the FMU's TELEM2 (``board.wiring.COMPANION_WIRES``),
the FMU's parameters that start its side of the uORB bridge there (``UORB_BRG_CFG`` 102, as
PX4's ``UXRCE_DDS_CFG`` names TELEM2), and for ``companion_att`` the attitude law moved to the
companion (``MC_ATT_IMPL`` 2 on the FMU, ``mc_att_control start`` on the companion), and for
``ros`` the companion's ``ros_bridge start`` (the edge itself is hil.ros.link's). The
companion gets the FMU's airframe (``SYS_AUTOSTART``) and the run's parameter overrides; it
applies those it declares.
"""

from __future__ import annotations

import os
import sys
from typing import Any

from board.wiring import COMPANION, COMPANION_WIRES, Wire

__all__ = ["COMPANION_ATT_FMU_PARAMS", "COMPANION_FMU_PARAMS", "COMPANION_ATT_STARTUP",
           "check_companion_att",
           "COMPANION_ROS_STARTUP",
           "add_companion", "companion_summary", "format_companion"]

#: FMU parameters for a companion on TELEM2: the bridge's FMU side starts from rcS.
COMPANION_FMU_PARAMS: dict[str, int] = {"UORB_BRG_CFG": 102}
#: FMU parameters for the attitude law on the companion (mc_att_companion, FMU fallback).
COMPANION_ATT_FMU_PARAMS: dict[str, int] = {"MC_ATT_IMPL": 2}
#: the companion's own start-up lines for ``companion_att``
COMPANION_ATT_STARTUP: tuple[str, ...] = ("mc_att_control start",)
#: the companion's own start-up lines for ``ros``
COMPANION_ROS_STARTUP: tuple[str, ...] = ("ros_bridge start",)
#: the TELEM2 link's baud (SER_TEL2_BAUD's default, the FTDI cable's rate on the companion)
LINK_BAUD = 921_600


def check_companion_att(airframe: int) -> None:
    """``companion_att`` moves the multicopter attitude law (MC_ATT_IMPL 2): refused, with the
    reason, for an airframe of another class (a plane has no multicopter attitude law to move;
    a VTOL's was not tried). An id without an airframe file (a test's) is left alone."""
    from hil.airframes import all_airframes

    frame = next((f for f in all_airframes() if f.id == airframe), None)
    if frame is not None and frame.vehicle_class != "multicopter":
        raise ValueError(f"the attitude law on the companion (companion_att) is the multicopter's;"
                         f" airframe {frame.id} ({frame.name}) is a {frame.vehicle_class}")


def _declared(params: dict[str, int]) -> dict[str, int]:
    """The parameters this build declares; the others are named on stderr and left out (the
    FMU refuses an unknown parameter at boot, and a module not yet in the tree has none)."""
    from hil.params_doc import param_def

    out = {}
    for name, value in params.items():
        if param_def(name) is None:
            print(f"hil: {name} is not declared in this build (its module is missing): "
                  f"not set", file=sys.stderr)
            continue
        out[name] = value
    return out


def add_companion(cfg: Any, boards: dict[str, Any], fmu_params: dict[str, Any],
                  seed: int) -> list[Wire]:
    """Add the companion board to ``boards`` and its settings to ``fmu_params`` (in place);
    return its wires. ``cfg`` is a :class:`hil.system.SystemConfig`."""
    from hil.orchestrator import BoardSpec

    root = os.path.join(cfg.out_dir, "companion")
    os.makedirs(root, exist_ok=True)
    if cfg.fresh_fram:  # as the FMU's FRAM: a reproducible run starts from a clean disk
        from companion.disk import PARAMS_FILE

        path = os.path.join(root, PARAMS_FILE)
        if os.path.exists(path):
            os.remove(path)
    wanted = dict(COMPANION_FMU_PARAMS)
    startup: tuple[str, ...] = ()
    if cfg.companion_att:
        check_companion_att(cfg.airframe)
        wanted.update(COMPANION_ATT_FMU_PARAMS)
        startup = COMPANION_ATT_STARTUP
    if cfg.ros:  # its topics to and from the ROS edge (hil.ros.link) over the "ros" port
        startup += COMPANION_ROS_STARTUP
    for name, value in _declared(wanted).items():
        fmu_params.setdefault(name, value)  # an explicit --param wins
    kwargs: dict[str, Any] = {
        "name": COMPANION, "seed": seed, "out_dir": root, "startup": startup,
        "params": {"SYS_AUTOSTART": cfg.airframe, **cfg.params}}
    if cfg.host_clock:
        kwargs["host_clock"] = "perf_counter"
    boards[COMPANION] = BoardSpec("companion.board:CompanionBoard", kwargs)
    return list(COMPANION_WIRES)


def companion_summary(orch: Any) -> dict[str, Any] | None:
    """The bridge's counters on both sides at the end of a run (``hil run``'s summary), or
    None without a companion. Each side's ``bridge_status`` (None if its bridge never ran)."""
    if COMPANION not in orch.handles:
        return None
    keys = ("link_ok", "link_lost_count", "tx_frames", "rx_frames", "tx_dropped",
            "rx_crc_errors", "rx_truncated", "rx_unknown_id", "rx_bad_size",
            "rx_garbage_bytes", "rx_lost", "tx_bytes", "rx_bytes")
    out: dict[str, Any] = {"alive": COMPANION not in orch.dead, "t_s": orch.t_ns / 1e9}
    for side in ("fmu", COMPANION):
        st = None
        if side not in orch.dead:
            st = orch.call(side, "topic", "bridge_status")
        out[side] = None if st is None else {k: st.get(k) for k in keys if k in st}
    if out["alive"]:
        out["modules"] = orch.call(COMPANION, "modules")
    return out


def format_companion(summary: dict[str, Any]) -> str:
    """One line of ``hil run``'s summary for the companion's bridge."""
    parts = []
    for side in ("fmu", COMPANION):
        st = summary.get(side)
        if st is None:
            parts.append(f"{side}: bridge not running")
            continue
        errors = sum(int(st.get(k) or 0) for k in ("rx_crc_errors", "rx_truncated",
                                                   "rx_unknown_id", "rx_bad_size"))
        load = ""
        t_s = float(summary.get("t_s") or 0.0)
        if t_s > 0 and st.get("tx_bytes") is not None:
            # 8N1: ten bits on the wire per byte
            rate = int(st["tx_bytes"]) / t_s
            load = f" ({rate / 1000:.1f} kB/s, {100 * rate * 10 / LINK_BAUD:.0f} % of the link)"
        parts.append(f"{side}: {st.get('tx_frames')} frames sent{load}, {st.get('rx_frames')} "
                     f"received, {errors} bad, {st.get('rx_lost')} lost, link "
                     f"{'up' if st.get('link_ok') else 'down'}")
    mods = ", ".join(summary.get("modules") or []) or "none"
    dead = "" if summary.get("alive") else " (the companion died)"
    return f"  companion{dead}: modules {mods}; uORB bridge {'; '.join(parts)}"
