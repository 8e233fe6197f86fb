"""``hil bench``: run the benchmark figures and print them (a table, or one JSON object)."""

from __future__ import annotations

import importlib
import json
import sys
import traceback

from bench import FIGURES, Figure


def run_figure(fig: Figure) -> float:
    module_name, func_name = fig.target.split(":")
    module = importlib.import_module(f"bench.{module_name}")
    return float(getattr(module, func_name)())


def main(as_json: bool = False, only: list[str] | None = None) -> int:
    figures = FIGURES
    if only:
        known = {f.key for f in FIGURES}
        unknown = [k for k in only if k not in known]
        if unknown:
            print(f"hil bench: unknown figure(s) {', '.join(unknown)}; known: "
                  f"{', '.join(sorted(known))}", file=sys.stderr)
            return 2
        figures = [f for f in FIGURES if f.key in only]
    results: dict[str, float | None] = {}
    failed = False
    progress = not as_json and sys.stderr.isatty()
    for fig in figures:
        if progress:
            print(f"  running {fig.key} ...", end="", flush=True, file=sys.stderr)
        try:
            value = run_figure(fig)
        except Exception:  # a broken benchmark must not hide the others
            failed = True
            value = None
            print(f"\nhil bench: {fig.key} failed:\n{traceback.format_exc()}", file=sys.stderr)
        results[fig.key] = value
        if progress:
            print("\r\033[K", end="", file=sys.stderr)
        if not as_json:
            shown = "FAILED" if value is None else _fmt(value)
            print(f"{fig.key:<40} {shown:>16}  {fig.unit:<14} {fig.about}")
    if as_json:
        print(json.dumps(results, indent=None))
    return 1 if failed else 0


def _fmt(v: float) -> str:
    if abs(v) >= 1000:
        return f"{v:,.0f}"
    if abs(v) >= 10:
        return f"{v:.1f}"
    return f"{v:.3f}"
