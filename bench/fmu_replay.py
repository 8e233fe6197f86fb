"""One board's own cost, replayed from a trace of the default flight (a tool, not a figure).

Wall-clock figures on a shared 2-vCPU machine move 10-30 % from one minute to the next, which
hides a 5 % change in a board. This tool takes everything else away: it records the default
flight once (one process, lookahead lockstep, as ``hil run`` steps it) into a lockstep trace,
then replays one board alone from the recorded inputs (``hil.trace.replay_board``: the board
must give the recorded outputs again, so a replay is also a regression check) and prints the
board's CPU time per virtual second. Replays of two trees (or of the compiled tier and the
sources, ``HIL_PURE=1``) on one trace run the same instructions on the same inputs; alternate
them to compare. ``python -m bench.fmu_replay [--trace FILE] [--board fmu] [--repeat N]``.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path


def record(path: str) -> None:
    from hil.flight import FlightConfig, fly

    with tempfile.TemporaryDirectory() as out:
        fly(FlightConfig(out_dir=out, mode="local", progress=False, plot=False,
                         pin_cpus=False, trace_path=path))


def replay(path: str, board: str, recorded_kwargs: dict) -> tuple[float, int, int]:
    """(CPU seconds, quanta, mismatches) of one replay, on fresh storage (a first boot, as
    recorded): every ``*_path``/``*_root`` argument of the board points into a new folder."""
    from hil.trace import replay_board

    with tempfile.TemporaryDirectory() as fresh:
        kwargs = {k: os.path.join(fresh, os.path.basename(v))
                  for k, v in recorded_kwargs.items()
                  if (k.endswith("_path") or k.endswith("_root")) and isinstance(v, str)}
        c0 = time.process_time()
        quanta, mismatches = replay_board(path, board, kwargs=kwargs)
        return time.process_time() - c0, quanta, len(mismatches)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--trace", default=os.path.join(tempfile.gettempdir(), "fmu-hil-flight.trace"),
                    help="trace file (recorded first if it does not exist)")
    ap.add_argument("--board", default="fmu")
    ap.add_argument("--repeat", type=int, default=1)
    args = ap.parse_args()
    if os.environ.get("HIL_PURE", "") in ("", "0"):
        from hil import native

        if sys.path and sys.path[0] in ("", "."):
            sys.path.pop(0)  # `python -m` from the repository: the cwd would shadow the tier
        native.activate()
    from hil import native as _native

    tier = "compiled tier" if _native.active() else "pure Python"
    if not Path(args.trace).exists():
        print(f"recording the default flight into {args.trace} ...", flush=True)
        record(args.trace)
    from hil.trace import read_trace

    info, _ = read_trace(args.trace)
    for _ in range(args.repeat):
        cpu, quanta, bad = replay(args.trace, args.board, info["boards"][args.board][1])
        virtual = quanta * info["quantum_ns"] * 1e-9
        print(f"{args.board}: {1000 * cpu / virtual:6.1f} ms CPU per virtual s "
              f"({cpu:.2f} s for {virtual:.1f} virtual s, {quanta} quanta, {tier}); "
              f"{'outputs as recorded' if not bad else f'{bad} quanta differ from the trace'}",
              flush=True)


if __name__ == "__main__":
    main()
