"""Which process bounds the default flight: each board's time per quantum, busy and waiting (a
tool, not a figure).

Runs the flight as ``hil run`` does (board processes, lookahead, the FMU pinned unless
``--no-pin``) with ``HIL_BOARD_STATS`` set, so that every board process times each request it
serves on the host clock (``hil.boardproc._serve``). A board that is busy most of the
time is the bound, and only making it cheaper speeds the run up; a board that waits a lot
while the others wait too points at the exchanges instead. The first ``--skip`` requests
(boot, arming) are left out; ``--quantum-us`` sets the lockstep quantum. Beside each board's
wall time it prints its thread CPU time (the same unless the host steals the CPU).
``python -m bench.board_busy [--no-pin] [--skip N] [--quantum-us Q]``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path


def _pct(values: list[float], f: float) -> float:
    return values[min(len(values) - 1, int(len(values) * f))]


def summarize(stats_dir: str, skip: int) -> list[dict]:
    """One row per board process: requests, busy and wait per request (us), busy share."""
    rows = []
    for path in sorted(Path(stats_dir).glob("*.json")):
        data = json.loads(path.read_text())
        busy, wait = data["busy_s"][skip:], data["wait_s"][skip:]
        cpu = data.get("busy_cpu_s", [])[skip:]
        if not busy:
            continue
        s = sorted(busy)
        total = sum(busy) + sum(wait)
        rows.append({"board": path.stem.rsplit("-", 1)[0], "requests": len(busy),
                     "busy_mean_us": 1e6 * sum(busy) / len(busy),
                     "busy_p50_us": 1e6 * _pct(s, 0.5), "busy_p90_us": 1e6 * _pct(s, 0.9),
                     "busy_p99_us": 1e6 * _pct(s, 0.99),
                     "wait_mean_us": 1e6 * sum(wait) / len(wait),
                     "busy_cpu_mean_us": 1e6 * sum(cpu) / len(cpu) if cpu else 0.0,
                     "busy_share": sum(busy) / total if total else 0.0})
    return rows


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--no-pin", action="store_true", help="leave CPU placement to the OS")
    ap.add_argument("--skip", type=int, default=20000, help="requests to leave out (start-up)")
    ap.add_argument("--quantum-us", type=int, default=0,
                    help="lockstep quantum (default: hil run's)")
    args = ap.parse_args()
    from hil import native

    if sys.path and sys.path[0] in ("", "."):
        sys.path.pop(0)  # `python -m` from the repository: the cwd would shadow the tier
    native.activate()
    from hil.boardproc import STATS_ENV
    from hil.flight import FlightConfig, fly

    with tempfile.TemporaryDirectory() as out, tempfile.TemporaryDirectory() as stats:
        os.environ[STATS_ENV] = stats  # the board processes inherit it
        cfg = FlightConfig(out_dir=out, progress=False, plot=False, pin_cpus=not args.no_pin)
        if args.quantum_us:
            cfg.quantum_ns = args.quantum_us * 1000
        try:
            summary = fly(cfg)
        finally:
            del os.environ[STATS_ENV]
        rows = summarize(stats, args.skip)
    for r in rows:
        print(f"{r['board']:4s} {r['requests']:7d} requests  busy mean {r['busy_mean_us']:6.1f} us "
              f"(p50 {r['busy_p50_us']:.0f}, p90 {r['busy_p90_us']:.0f}, p99 "
              f"{r['busy_p99_us']:.0f}; CPU {r['busy_cpu_mean_us']:.1f})  "
              f"wait mean {r['wait_mean_us']:6.1f} us  busy {100 * r['busy_share']:.0f} %")
    print(f"rtf {summary['rtf']}; {'compiled tier' if summary['compiled'] else 'pure Python'}; "
          f"{summary.get('cpus') or 'CPUs not pinned'}")


if __name__ == "__main__":
    main()
