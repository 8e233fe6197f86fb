"""GPS faults: the u-blox module on the FMU's GPS connector (UART4) misbehaves.

They reach the receiver model through the FMU board's ``ctl_gps_fault`` hook and change what
the module computes and sends (UBX NAV-PVT fix type, accuracies, position, MON-HW jamming
indicator), never what the GPS driver or the estimator believe. Each kind is one
``ctl_gps_fault`` setting given on start and taken back on stop (:func:`_gps_kind`), so it
works on an in-process FMU as on the orchestrated system.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from hil.faults import FaultError, Rig, switch_kind
from hil.faults._rig import board_call


def _gps_kind(name: str, what: str, doc: str, on: Callable[[dict[str, Any]], tuple],
              off: tuple, **params: Any) -> None:
    """A kind giving the receiver's fault ``what`` the arguments ``on(params)``, and ``off``
    when it stops."""

    def apply(rig: Rig, target: str, p: dict[str, Any], active: bool) -> None:
        board_call(rig, name, "fmu", "gps_fault", what, *(on(p) if active else off))

    switch_kind(name, apply, level="gps", doc=doc, targets=("gps",), **params)


def _factor(p: dict[str, Any]) -> tuple:
    factor = float(p["factor"])
    if factor < 1.0:
        raise FaultError(f"fault gps_degraded: factor {factor} below 1")
    return (factor,)


def _jam_level(p: dict[str, Any]) -> tuple:
    level = int(p["level_ind"])
    if not 0 <= level <= 255:
        raise FaultError(f"fault gps_jamming: level_ind {level} outside 0..255")
    return (level,)


_gps_kind("gps.lost_fix", "lose_fix",
          "The receiver loses its fix (sky blocked: a building, a hangar, a canopy): it "
          "keeps sending navigation messages with fix type 0 and no satellites used. "
          "The estimator stops fusing GPS, the position becomes invalid after its "
          "timeout, and the commander falls back from position modes (a Return becomes "
          "a Land or a Descend); arming in position modes is refused.",
          lambda p: (True,), (False,))
_gps_kind("gps.degraded", "degrade",
          "Accuracy worse by ``factor`` (multipath near buildings, few satellites, poor "
          "geometry): the position error and the reported hAcc/vAcc/sAcc grow alike. "
          "The estimator's GPS quality checks (EKF2_REQ_EPH and friends) fail, so arming "
          "is refused until it improves.",
          _factor, (1.0,), factor=10.0)
_gps_kind("gps.jamming", "jam",
          "RF jamming of the GNSS band: the receiver's jamming indicator (MON-HW jamInd, "
          "0..255) rises to ``level_ind``, noise rises, C/N0 and satellites drop, "
          "accuracy degrades, and above 230 the fix is lost.",
          _jam_level, (0,), level_ind=200)
_gps_kind("gps.jump", "jump",
          "The reported position jumps by an offset (a multipath lock onto a reflection, "
          "spoofing) while the fix and its claimed accuracy stay good. The estimator's "
          "GPS innovation check rejects the jump and, when it persists, resets to it.",
          lambda p: (float(p["north_m"]), float(p["east_m"]), float(p["down_m"])),
          (0.0, 0.0, 0.0), north_m=50.0, east_m=0.0, down_m=0.0)
_gps_kind("gps.absent", "set_absent",
          "The GPS module stops talking (unplugged, its supply lost, a dead module): "
          "nothing arrives on UART4. The GPS driver times out and rescans baud rates; "
          "the estimator loses GPS as for a lost fix, and the preflight checks say "
          "\"no GPS\".",
          lambda p: (True,), (False,))
