"""``mc_att_select``: swap the attitude controller when ``MC_ATT_IMPL`` changes (issue 23).

PX4 picks some implementations by parameter at boot only (``SYS_MC_EST_GROUP``); here the
attitude controller can also be swapped in flight, so a ground station can do through a
parameter what a shell user does with ``mc_att_control stop; mc_att_control_so3 start``.

On ``parameter_update`` the selector compares ``MC_ATT_IMPL`` with the value it saw last; when
it changed, it stops the running attitude controller and starts the selected one, both inside
this one work item run (work items are atomic: no attitude update can fall between the stop
and the start). The newcomer's first output then comes on the next attitude update, continued
from the old one's last rate setpoint (``mc_att_control/handover.py``). If the selected one does
not start, the old one is started again, so the vehicle never stays without one.

Each controller records its own number in ``MC_ATT_IMPL`` when it starts, so the parameter
names the running controller after a shell swap too: a later unrelated parameter change does
not undo the shell swap, and setting the parameter back swaps back.
"""

from __future__ import annotations

from typing import Final

from firmware.modules.mc_att_control.handover import ATT_CONTROLLERS
from firmware.platform.module import WorkItemModule
from firmware.platform.params import ParamDef

__all__ = ["IMPLS", "PARAMS", "McAttSelectModule"]

#: MC_ATT_IMPL value -> attitude controller module (shell name)
IMPLS: Final[dict[int, str]] = ATT_CONTROLLERS

PARAMS: tuple[ParamDef, ...] = (
    ParamDef("MC_ATT_IMPL", "INT32", 0, min=0, max=2, group="Multicopter Attitude Control",
             short="Attitude controller implementation",
             long="Which multicopter attitude controller runs. Changing it in flight swaps "
                  "the controllers without a step in the rate setpoint (mc_att_select); a "
                  "controller started from the shell sets it to its own number.",
             values={0: "mc_att_control (quaternion, PX4)",
                     1: "mc_att_control_so3 (geometric SO(3), Lee 2010)",
                     2: "mc_att_companion (the companion computer's law, FMU law as "
                        "fallback)"}),
)


class McAttSelectModule(WorkItemModule):
    """Watches MC_ATT_IMPL and swaps the attitude controllers when it changes."""

    NAME = "mc_att_select"
    DESCRIPTION = "attitude controller selection by MC_ATT_IMPL"
    WQ = "wq:lp_default"
    #: a parameter comparison; the swap itself is the modules' start and stop
    CPU_COST_NS = 5_000
    PARAMS = PARAMS

    def _start(self) -> None:
        item = self.work_item
        assert item is not None
        self.sub_param = self.subscribe_callback(item, "parameter_update")
        self.sub_param.update()          # the boot's parameters are not a change
        self.seen = int(self.param("MC_ATT_IMPL"))
        self.swaps = 0

    def running_impl(self) -> str | None:
        """The attitude controller running now, if any."""
        modules = self.system.modules
        return next((n for n in IMPLS.values() if modules.is_running(n)), None)

    def run(self) -> None:
        if self.sub_param.update() is None:
            return
        value = int(self.param("MC_ATT_IMPL"))
        if value == self.seen:
            return
        self.seen = value
        target = IMPLS.get(value)
        if target is None:
            self.warn(f"MC_ATT_IMPL {value}: no such attitude controller, none swapped")
            return
        self.swap(target)

    def swap(self, target: str) -> bool:
        """Stop the running attitude controller and start ``target``; on failure restart the
        old one. Returns whether ``target`` runs."""
        modules = self.system.modules
        old = self.running_impl()
        if old == target:
            return True
        if old is not None:
            modules.stop(old)
        if modules.start(target) == 0:
            self.swaps += 1
            self.info(f"MC_ATT_IMPL: {old or 'none'} -> {target}")
            return True
        self.error(f"MC_ATT_IMPL: {target} did not start"
                   + (f", {old} restarted" if old is not None else ""))
        if old is not None:
            modules.start(old)
        return False

    def status_lines(self) -> list[str]:
        return [f"MC_ATT_IMPL {self.seen}: {IMPLS.get(self.seen, '?')}, running: "
                f"{self.running_impl() or 'none'}, {self.swaps} swaps"]
