"""GPS faults: the u-blox module on the FMU's GPS connector (UART4) misbehaves.

They reach the receiver model through the FMU board's ``ctl_gps_fault`` hook and change what
the module computes and sends (UBX NAV-PVT fix type, accuracies, position, MON-HW jamming
indicator), never what the GPS driver or the estimator believe.
"""

from __future__ import annotations

from typing import Any

from hil.faults import FaultError, fault_kind


def _gps(rig: Any, what: str, *args: Any) -> None:
    rig.orch.call("fmu", "gps_fault", what, *args)


@fault_kind("gps.lost_fix", level="gps", targets=("gps",),
            doc="The receiver loses its fix (sky blocked: a building, a hangar, a canopy): it "
                "keeps sending navigation messages with fix type 0 and no satellites used. "
                "The estimator stops fusing GPS, the position becomes invalid after its "
                "timeout, and the commander falls back from position modes (a Return becomes "
                "a Land or a Descend); arming in position modes is refused.")
def lost_fix_start(rig: Any, target: str, params: dict[str, Any], t_ns: int) -> None:
    _gps(rig, "lose_fix", True)


@lost_fix_start.stopper
def lost_fix_stop(rig: Any, target: str, params: dict[str, Any], t_ns: int, token: Any) -> None:
    _gps(rig, "lose_fix", False)


@fault_kind("gps.degraded", level="gps", targets=("gps",), factor=10.0,
            doc="Accuracy worse by ``factor`` (multipath near buildings, few satellites, poor "
                "geometry): the position error and the reported hAcc/vAcc/sAcc grow alike. "
                "The estimator's GPS quality checks (EKF2_REQ_EPH and friends) fail, so arming "
                "is refused until it improves.")
def degraded_start(rig: Any, target: str, params: dict[str, Any], t_ns: int) -> None:
    factor = float(params["factor"])
    if factor < 1.0:
        raise FaultError(f"fault gps_degraded: factor {factor} below 1")
    _gps(rig, "degrade", factor)


@degraded_start.stopper
def degraded_stop(rig: Any, target: str, params: dict[str, Any], t_ns: int, token: Any) -> None:
    _gps(rig, "degrade", 1.0)


@fault_kind("gps.jamming", level="gps", targets=("gps",), level_ind=200,
            doc="RF jamming of the GNSS band: the receiver's jamming indicator (MON-HW jamInd, "
                "0..255) rises to ``level_ind``, noise rises, C/N0 and satellites drop, "
                "accuracy degrades, and above 230 the fix is lost.")
def jam_start(rig: Any, target: str, params: dict[str, Any], t_ns: int) -> None:
    level = int(params["level_ind"])
    if not 0 <= level <= 255:
        raise FaultError(f"fault gps_jamming: level_ind {level} outside 0..255")
    _gps(rig, "jam", level)


@jam_start.stopper
def jam_stop(rig: Any, target: str, params: dict[str, Any], t_ns: int, token: Any) -> None:
    _gps(rig, "jam", 0)


@fault_kind("gps.jump", level="gps", targets=("gps",), north_m=50.0, east_m=0.0, down_m=0.0,
            doc="The reported position jumps by an offset (a multipath lock onto a reflection, "
                "spoofing) while the fix and its claimed accuracy stay good. The estimator's "
                "GPS innovation check rejects the jump and, when it persists, resets to it.")
def jump_start(rig: Any, target: str, params: dict[str, Any], t_ns: int) -> None:
    _gps(rig, "jump", float(params["north_m"]), float(params["east_m"]), float(params["down_m"]))


@jump_start.stopper
def jump_stop(rig: Any, target: str, params: dict[str, Any], t_ns: int, token: Any) -> None:
    _gps(rig, "jump", 0.0, 0.0, 0.0)


@fault_kind("gps.absent", level="gps", targets=("gps",),
            doc="The GPS module stops talking (unplugged, its supply lost, a dead module): "
                "nothing arrives on UART4. The GPS driver times out and rescans baud rates; "
                "the estimator loses GPS as for a lost fix, and the preflight checks say "
                "\"no GPS\".")
def absent_start(rig: Any, target: str, params: dict[str, Any], t_ns: int) -> None:
    _gps(rig, "set_absent", True)


@absent_start.stopper
def absent_stop(rig: Any, target: str, params: dict[str, Any], t_ns: int, token: Any) -> None:
    _gps(rig, "set_absent", False)
