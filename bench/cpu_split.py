"""CPU time per virtual second of the default flight, split by board (a tool, not a figure).

Runs the flight one-process (``mode="local"``) and charges the process CPU time of each
board's quantum to that board; the rest is the world, the orchestrator and the ground station.
CPU time moves less than wall time when other work shares the machine (though a busy
neighbour still slows a core by 10-30 % here), so this is the number to watch while optimising
a board. ``python -m bench.cpu_split [--pipeline] [--pure]``: the compiled tier when it is
fresh (as ``hil`` runs), the sources with ``--pure``.
"""

from __future__ import annotations

import argparse
import collections
import sys
import tempfile
import time


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--pipeline", action="store_true", help="lookahead lockstep")
    ap.add_argument("--pure", action="store_true", help="the sources, not the compiled tier")
    args = ap.parse_args()
    if not args.pure:
        from hil import native

        if sys.path and sys.path[0] in ("", "."):
            sys.path.pop(0)  # `python -m` from the repository: the cwd would shadow the tier
        native.activate()
    from board.endpoint import LocalHandle
    from hil.flight import FlightConfig, fly
    spent: collections.Counter[str] = collections.Counter()
    orig = LocalHandle.post_advance
    clock = time.process_time

    def post_advance(self, start_ns, until_ns, inputs):  # noqa: ANN001, ANN202
        t0 = clock()
        orig(self, start_ns, until_ns, inputs)
        spent[self.name] += clock() - t0

    LocalHandle.post_advance = post_advance  # type: ignore[method-assign]
    cfg = dict(mode="local", progress=False, plot=False, pipeline=args.pipeline)
    t0 = clock()
    with tempfile.TemporaryDirectory() as out:
        summary = fly(FlightConfig(out_dir=out, **cfg))
    total = clock() - t0
    virtual = summary["phases"][-1]["t_s"]
    rest = total - sum(spent.values())
    for name, value in [*spent.most_common(), ("world+orchestrator+gcs", rest),
                        ("total", total)]:
        print(f"{name:24s} {value:7.2f} s CPU  {1000 * value / virtual:6.0f} ms per virtual s")
    print(f"{'compiled tier' if summary['compiled'] else 'pure Python'}; "
          f"virtual {virtual:.1f} s; FMU-bound rtf {virtual / spent['fmu']:.2f}, "
          f"one-process rtf {virtual / total:.2f}")


if __name__ == "__main__":
    main()
