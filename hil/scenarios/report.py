"""Verdict tables for one scenario run (text for a terminal, the dict for --json)."""

from __future__ import annotations

from typing import Any

__all__ = ["format_table", "repro_command"]


def _t(v: float | None) -> str:
    return "" if v is None else f"{v:.3f}"


def repro_command(source: str, seed: int, out_dir: str | None = None,
                  params: dict[str, Any] | None = None, one_process: bool = False) -> str:
    """The ``hil scenario`` command line that runs this scenario again exactly."""
    cmd = f"hil scenario {source} --seed {seed}"
    for k, v in sorted((params or {}).items()):
        cmd += f" --param {k}={v}"
    if one_process:
        cmd += " --one-process"
    if out_dir:
        cmd += f" --out {out_dir}"
    return cmd


def format_table(result: Any) -> str:
    """The verdict table: expectation, verdict, time met or broken, latency from its event."""
    rows = [("expectation", "verdict", "met at s", "broken at s", "after event s")]
    for e in result.expectations:
        verdict = e.verdict.upper() + (f" ({e.reason})" if e.reason else "")
        rows.append((e.text, verdict, _t(e.t_met_s), _t(e.t_broken_s),
                     _t(e.latency_s)))
    widths = [min(max(len(r[i]) for r in rows), 70 if i == 0 else 60) for i in range(5)]
    lines = []
    for j, r in enumerate(rows):
        lines.append("  ".join(c.ljust(w) if len(c) <= w else c for c, w in zip(r, widths)))
        if j == 0:
            lines.append("  ".join("-" * w for w in widths))
    head = (f"scenario {result.name} (seed {result.seed}): "
            f"{'PASS' if result.passed else 'FAIL'} at t={result.t_end_s:.2f} s virtual, "
            f"{result.wall_s:.1f} s wall, rtf {result.rtf:.2f}")
    tail = []
    if result.aborted:
        tail.append(f"aborted: {result.aborted}")
    if result.events:
        tail.append("events: " + ", ".join(f"{k} {v:.3f} s" for k, v in
                                           sorted(result.events.items(), key=lambda kv: kv[1])))
    if result.log:
        tail.append(f"log: {result.log}")
    if result.trace:
        tail.append(f"trace: {result.trace}")
    return "\n".join([head, *lines, *tail])
