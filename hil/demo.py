"""``hil run`` until the flight stack exists: the lockstep system with stand-in firmware.

Two board processes (FMU and IO stand-ins talking over the 1.5 Mbit/s link) and the JSBSim F450
world, advanced in lockstep; prints what crossed the wires and the real-time factor.
"""

from __future__ import annotations

import json
import sys
import time

from board.wiring import WORLD, Wire, uart_link
from hil.orchestrator import BoardSpec, Orchestrator
from hil.worldlink import TRUTH_FIELDS, WorldPorts

NS_PER_S = 1_000_000_000


def main(seed: int = 1, duration_s: float = 10.0, as_json: bool = False) -> int:
    boards = {"fmu": BoardSpec("board.stock:LinkDemoFmu", {"seed": seed}),
              "io": BoardSpec("board.stock:LinkDemoIo", {"seed": seed})}
    wiring = [*uart_link(("fmu", "io_link"), ("io", "fmu_link")),
              Wire((WORLD, "truth"), ("fmu", "truth")),
              *[Wire(("io", f"pwm{i}"), (WORLD, f"esc{i}")) for i in range(1, 5)]]
    world = WorldPorts(seed=seed)
    duration_ns = int(duration_s * NS_PER_S)
    say = (lambda msg: None) if as_json else (lambda msg: print(msg, flush=True))
    say(f"hil run: FMU and IO board processes + JSBSim F450, {duration_s:g} s virtual, "
        f"seed {seed}")
    t0 = time.perf_counter()
    with Orchestrator(boards, wiring, world=world, log=say) as orch:
        startup = time.perf_counter() - t0
        step_ns = NS_PER_S
        while orch.t_ns < duration_ns:
            orch.run(duration_ns=min(step_ns, duration_ns - orch.t_ns))
            say(f"  t = {orch.t_ns / NS_PER_S:5.1f} s   real-time factor {orch.rtf:5.1f}")
        fmu = orch.call("fmu", "stats")
        io = orch.call("io", "stats")
        truth = dict(zip(TRUTH_FIELDS, fmu.pop("last_truth")))
        summary = {
            "t_s": orch.t_ns / NS_PER_S,
            "rtf": round(orch.rtf, 2),
            "startup_s": round(startup, 3),
            "quanta": orch.quanta,
            "fmu": fmu,
            "io": io,
            "dead_boards": dict(orch.dead),
            "vehicle": {"alt_m": truth["alt_m"], "agl_m": truth["agl_m"],
                        "accel_body_m_s2": truth["accel_body_m_s2"]},
        }
    if as_json:
        json.dump(summary, sys.stdout)
        print()
    else:
        say(f"done: {summary['t_s']:.1f} s virtual in lockstep, real-time factor "
            f"{summary['rtf']:.1f} (start-up {startup:.2f} s)")
        say(f"  FMU: {fmu['frames_sent']} frames sent, {fmu['replies']} replies received, "
            f"{fmu['truth_samples']} truth samples")
        say(f"  IO:  {io['frames_answered']} frames answered")
        ax, ay, az = summary["vehicle"]["accel_body_m_s2"]
        say(f"  vehicle at rest: AGL {summary['vehicle']['agl_m']:.2f} m, specific force "
            f"({ax:.2f}, {ay:.2f}, {az:.2f}) m/s^2")
    return 0 if not orch.dead else 1
