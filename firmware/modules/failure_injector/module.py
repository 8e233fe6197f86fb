"""failure_injector: MAV_CMD_INJECT_FAILURE handed to the simulator, as PX4 does it in SITL.

PX4 (docs "System Failure Injection"): with ``SYS_FAILURE_EN`` 1 the MAVLink receiver
publishes MAV_CMD_INJECT_FAILURE on ``vehicle_command`` and leaves the answer to the module
that can act on it (in SITL the simulator module, which stops or corrupts what it sends for
the sensor, or the motor failure plugin); with 0 the receiver answers DENIED itself (done in
``firmware/modules/mavlink/commands.py``). Here the simulator is the orchestrator: this module
hands (unit, type, instance) to the board (``FmuV2Board.request_failure``), the orchestrator
maps the pair onto a fault of its own catalogue (hil/faults/inject_failure.py: a chip's
registers, a bus or wire, the world, the RC or ground link) and answers; the answer becomes
the ``vehicle_command_ack`` (ACCEPTED, UNSUPPORTED for a pair without a fault, DENIED for a
sensor instance the vehicle lacks, FAILED if applying it failed) with a STATUSTEXT. Nothing
here touches flight-stack state: the drivers, estimator and commander notice the fault as they
would on a real vehicle.

A board with no fault injector behind it (no orchestrator hook, or no ``request_failure`` at
all) gets UNSUPPORTED "no fault injector attached": from the orchestrator at once, or from
here after :data:`REPLY_TIMEOUT_US` if nothing ever answers.

The command's float parameters are checked before anything is asked (PX4 rounds them with
``(int)(param + 0.5f)``, undefined for NaN): unit, type and instance must be whole numbers in
0..255, else DENIED.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, ClassVar, Final

from firmware.platform.module import WorkItemModule

if TYPE_CHECKING:
    from firmware.system import System

__all__ = ["CMD_INJECT_FAILURE", "FailureInjectorModule", "REPLY_TIMEOUT_US", "command_fields"]

CMD_INJECT_FAILURE: Final = 420
ACCEPTED: Final = 0
DENIED: Final = 2
UNSUPPORTED: Final = 3
#: how long an answer may take before the request counts as unanswered (the orchestrator
#: answers within one or two lockstep quanta: ~1 ms)
REPLY_TIMEOUT_US: Final = 1_000_000
NO_INJECTOR: Final = "no fault injector attached"


def command_fields(p1: float, p2: float, p3: float) -> tuple[int, int, int] | None:
    """(unit, type, instance) from the command's param1..3, or None if one is not a whole
    number in 0..255 (NaN, infinite, fractional, negative, huge)."""
    out: list[int] = []
    for v in (p1, p2, p3):
        f = float(v)
        if not math.isfinite(f) or f != math.floor(f) or not 0.0 <= f <= 255.0:
            return None
        out.append(int(f))
    return out[0], out[1], out[2]


class _Pending:
    """A request sent to the board, waiting for its answer."""

    def __init__(self, cmd: Any, deadline_us: int,
                 fields: tuple[int, int, int] = (-1, -1, -1)) -> None:
        self.fields = fields
        self.command = int(cmd.command)
        self.source_system = int(cmd.source_system)
        self.source_component = int(cmd.source_component)
        self.from_external = bool(cmd.from_external)
        self.deadline_us = deadline_us


class FailureInjectorModule(WorkItemModule):
    NAME = "failure_injector"
    DESCRIPTION = "MAV_CMD_INJECT_FAILURE to the simulator's fault injector (PX4 SITL's role)"
    WQ = "wq:lp_default"
    CPU_COST_NS = 20_000
    #: commands this module answers with its own vehicle_command_ack (see the commander)
    VEHICLE_COMMANDS: ClassVar[frozenset[int]] = frozenset({CMD_INJECT_FAILURE})

    def __init__(self, system: System, args: Sequence[str] = ()) -> None:
        super().__init__(system, args)
        self._pending: dict[int, _Pending] = {}
        self._replies: list[tuple[int, int, str]] = []
        self._seq = 0
        self.requests = 0
        self.answers: list[tuple[int, int, int, int, str]] = []   # unit, type, inst, result, text
        self._sys_id = 1

    def _start(self) -> None:
        assert self.work_item is not None
        orb = self.platform.orb
        self._sub_cmd = self.subscribe_callback(self.work_item, "vehicle_command")
        self._sub_cmd.copy()  # only commands from now on
        self._pub_ack = self.advertise("vehicle_command_ack")
        self._ack = orb.new("vehicle_command_ack")
        params = self.system.params
        if params is not None:
            self._sys_id = int(params.get("MAV_SYS_ID", 1) or 1)
        hw = getattr(self.system, "hw", None)
        if hw is not None and hasattr(hw, "failure_reply_handler"):
            hw.failure_reply_handler = self._on_reply

    def _stop(self) -> None:
        hw = getattr(self.system, "hw", None)
        if hw is not None and getattr(hw, "failure_reply_handler", None) == self._on_reply:
            hw.failure_reply_handler = None

    def _on_reply(self, t_ns: int, payload: Any) -> None:
        """The orchestrator's answer (board input, interrupt context): handled in ``run``."""
        try:
            seq, result, text = payload
            self._replies.append((int(seq), int(result), str(text)))
        except (TypeError, ValueError):
            return  # not an answer this module asked for
        if self.work_item is not None:
            self.work_item.schedule_now()

    def run(self) -> None:
        now = self.platform.time_us()
        while True:
            cmd = self._sub_cmd.update()
            if cmd is None:
                break
            if int(cmd.command) == CMD_INJECT_FAILURE and \
                    int(cmd.target_system) in (0, self._sys_id):
                self._request(cmd, now)
        replies, self._replies = self._replies, []
        for seq, result, text in replies:
            pending = self._pending.pop(seq, None)
            if pending is not None:
                self._answer(pending, result, text)
        for seq in [s for s, p in self._pending.items() if p.deadline_us <= now]:
            self._answer(self._pending.pop(seq), UNSUPPORTED, f"{NO_INJECTOR} (no answer)")
        if self._pending and self.work_item is not None:
            self.work_item.schedule_delayed(
                max(1, min(p.deadline_us for p in self._pending.values()) - now))

    def _request(self, cmd: Any, now_us: int) -> None:
        fields = command_fields(cmd.param1, cmd.param2, cmd.param3)
        pending = _Pending(cmd, now_us + REPLY_TIMEOUT_US, fields or (-1, -1, -1))
        if fields is None:
            self._answer(pending, DENIED, f"bad parameters (unit {cmd.param1}, type "
                                          f"{cmd.param2}, instance {cmd.param3})")
            return
        hw = getattr(self.system, "hw", None)
        if hw is None or not hasattr(hw, "request_failure"):
            self._answer(pending, UNSUPPORTED, NO_INJECTOR)
            return
        self._seq = (self._seq + 1) & 0xFFFF
        self._pending[self._seq] = pending
        self.requests += 1
        hw.request_failure(self._seq, *fields)

    def _answer(self, p: _Pending, result: int, text: str) -> None:
        if result == ACCEPTED:
            self.info(f"Failure injection: {text}")
        else:
            self.warn(f"Failure injection refused: {text}")
        a = self._ack
        a.timestamp = self.platform.time_us()
        a.command = p.command
        a.result = result
        a.target_system = p.source_system
        a.target_component = p.source_component
        a.from_external = p.from_external
        self._pub_ack.publish(a)
        self.answers.append((*p.fields, result, text))
        del self.answers[:-16]

    def status_lines(self) -> list[str]:
        out = [f"requests: {self.requests}, waiting: {len(self._pending)}"]
        out += [f"unit {u} type {t} instance {i}: result {r} ({text})"
                for u, t, i, r, text in self.answers]
        return out
