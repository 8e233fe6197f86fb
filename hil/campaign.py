"""``hil campaign``: scenarios x seeds x parameter values, run in parallel, one report.

Runs fan out to local worker processes (``concurrent.futures.ProcessPoolExecutor``, a live
progress line) or to a Dask cluster (``--dask ADDRESS``, or ``--dask local`` for a
``distributed.LocalCluster``). Every run is a plain function of plain data
(:func:`run_one`), so a worker needs only this package installed, and results are the same
wherever a run lands: a run is deterministic in its scenario, seed and parameters.

The report (``report.md`` and ``report.json`` in the output folder) lists pass/fail per run,
the virtual time to each expectation, the worst (latest) time per expectation across runs,
the real-time factor of each run, and for each failure the ``hil scenario`` command that
reproduces it.
"""

from __future__ import annotations

import itertools
import json
import os
import sys
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

__all__ = ["Run", "expand", "main", "parse_seeds", "run_campaign", "run_one", "write_report"]


@dataclass(frozen=True)
class Run:
    scenario: str                    # file path
    seed: int
    params: tuple[tuple[str, float], ...] = ()

    @property
    def key(self) -> str:
        p = "".join(f"_{k}={v}" for k, v in self.params)
        return f"{Path(self.scenario).stem}_s{self.seed}{p}"


def parse_seeds(text: str) -> list[int]:
    """``1-4``, ``1,3,7``, ``5`` or a mix (``1-3,9``)."""
    seeds: list[int] = []
    for part in str(text).split(","):
        part = part.strip()
        try:
            if "-" in part:
                a, b = (int(x) for x in part.split("-", 1))
                if b < a:
                    raise ValueError
                seeds += range(a, b + 1)
            else:
                seeds.append(int(part))
        except ValueError:
            raise ValueError(f"--seeds {text!r}: expected N, A-B or a comma list") from None
    if any(s < 0 for s in seeds):
        raise ValueError(f"--seeds {text!r}: seeds are non-negative")
    return list(dict.fromkeys(seeds))


def expand(scenarios: Iterable[str], seeds: Iterable[int],
           params: dict[str, list[Any]] | None = None) -> list[Run]:
    """Every scenario x seed x combination of parameter values."""
    names = sorted(params or {})
    combos = list(itertools.product(*((params or {})[n] for n in names))) if names else [()]
    return [Run(sc, seed, tuple(zip(names, combo)))
            for sc in scenarios for seed in seeds for combo in combos]


def run_one(run: Run, out_root: str, one_process: bool = False) -> dict[str, Any]:
    """Run one scenario variation; a plain dict result (picklable, JSON-able)."""
    import multiprocessing

    from hil.scenarios import ScenarioError, load_scenario, run_scenario
    from hil.scenarios.report import repro_command

    # A daemonic worker (Dask's by default) may not start the board processes: run both
    # boards in the worker then (same results, see hil.system's one-process mode).
    one_process = one_process or bool(multiprocessing.current_process().daemon)
    out = os.path.join(out_root, "runs", run.key)
    params = dict(run.params)
    base = {"scenario": run.scenario, "seed": run.seed, "params": params, "out_dir": out,
            "command": repro_command(run.scenario, run.seed, out, params, one_process)}
    try:
        sc = load_scenario(run.scenario)
        res = run_scenario(sc, seed=run.seed, out_dir=out,
                           one_process=True if one_process else None, params=params)
    except ScenarioError as exc:
        return base | {"name": Path(run.scenario).stem, "passed": False, "error": str(exc),
                       "expectations": [], "rtf": 0.0, "wall_s": 0.0, "t_end_s": 0.0,
                       "known_failure": ""}
    except Exception as exc:  # noqa: BLE001 - one broken run must not end the campaign
        return base | {"name": Path(run.scenario).stem, "passed": False,
                       "error": f"{type(exc).__name__}: {exc}", "expectations": [],
                       "rtf": 0.0, "wall_s": 0.0, "t_end_s": 0.0, "known_failure": ""}
    d = res.as_dict()
    return base | {"name": res.name, "passed": res.passed, "error": res.aborted,
                   "expectations": d["expectations"], "rtf": res.rtf, "wall_s": res.wall_s,
                   "t_end_s": res.t_end_s, "events": res.events,
                   "known_failure": sc.known_failure}


def _progress(done: int, total: int, failed: int, t0: float, stream: Any) -> None:
    if stream is None:
        return
    stream.write(f"\rhil campaign: {done}/{total} runs, {failed} failed, "
                 f"{time.perf_counter() - t0:.0f} s")
    stream.flush()


def run_campaign(runs: list[Run], out_dir: str, *, jobs: int | None = None,
                 dask: str | None = None, one_process: bool = False,
                 progress: Any = sys.stderr) -> list[dict[str, Any]]:
    """Run every variation; results in the order of ``runs``."""
    os.makedirs(out_dir, exist_ok=True)
    out_root = os.path.abspath(out_dir)
    results: list[dict[str, Any] | None] = [None] * len(runs)
    t0 = time.perf_counter()
    failed = 0
    if dask:
        from distributed import Client, LocalCluster, as_completed

        cluster = None
        if dask == "local":
            cluster = LocalCluster(n_workers=jobs or os.cpu_count() or 1, threads_per_worker=1,
                                   processes=True, dashboard_address=None)
            client = Client(cluster)
        else:
            client = Client(dask)
        try:
            futs = {client.submit(run_one, r, out_root, one_process, pure=False): i
                    for i, r in enumerate(runs)}
            for n, fut in enumerate(as_completed(futs), 1):
                res = fut.result()
                results[futs[fut]] = res
                failed += not res["passed"]
                _progress(n, len(runs), failed, t0, progress)
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    else:
        from concurrent.futures import ProcessPoolExecutor
        from concurrent.futures import as_completed as cf_completed
        from multiprocessing import get_context

        with ProcessPoolExecutor(max_workers=jobs or os.cpu_count() or 1,
                                 mp_context=get_context("spawn")) as pool:
            futs = {pool.submit(run_one, r, out_root, one_process): i
                    for i, r in enumerate(runs)}
            for n, fut in enumerate(cf_completed(futs), 1):
                res = fut.result()
                results[futs[fut]] = res
                failed += not res["passed"]
                _progress(n, len(runs), failed, t0, progress)
    if progress is not None:
        progress.write("\n")
    return [r for r in results if r is not None]


def _summary(results: list[dict[str, Any]]) -> dict[str, Any]:
    worst: dict[tuple[str, str], dict[str, Any]] = {}
    for r in results:
        for e in r["expectations"]:
            lat = e.get("latency_s")
            key = (r["name"], e["text"])
            w = worst.setdefault(key, {"scenario": r["name"], "expectation": e["text"],
                                       "worst_latency_s": None, "runs": 0, "failed": 0,
                                       "worst_run": None})
            w["runs"] += 1
            w["failed"] += e["verdict"] != "pass"
            if lat is not None and (w["worst_latency_s"] is None or lat > w["worst_latency_s"]):
                w["worst_latency_s"] = lat
                w["worst_run"] = r["command"]
    return {"runs": len(results), "passed": sum(r["passed"] for r in results),
            "failed": sum(not r["passed"] for r in results),
            "worst": sorted(worst.values(), key=lambda w: (w["scenario"], w["expectation"]))}


def write_report(results: list[dict[str, Any]], out_dir: str) -> tuple[str, str]:
    """report.json (everything) and report.md (tables); returns both paths."""
    summary = _summary(results)
    jpath = os.path.join(out_dir, "report.json")
    with open(jpath, "w", encoding="utf-8") as f:
        json.dump({"summary": summary, "runs": results}, f, indent=1, default=str)
    lines = ["# hil campaign report", "",
             f"{summary['runs']} runs: {summary['passed']} passed, {summary['failed']} failed.",
             "", "## Runs", "",
             "| scenario | seed | params | verdict | virtual s | wall s | rtf |",
             "|---|---|---|---|---|---|---|"]
    for r in results:
        params = ", ".join(f"{k}={v}" for k, v in r["params"].items()) or "-"
        verdict = "pass" if r["passed"] else "**FAIL**"
        lines.append(f"| {r['name']} | {r['seed']} | {params} | {verdict} | "
                     f"{r['t_end_s']:.2f} | {r['wall_s']:.1f} | {r['rtf']:.2f} |")
    lines += ["", "## Time to each expectation (worst case over runs)", "",
              "| scenario | expectation | runs | failed | worst time after its event, s |",
              "|---|---|---|---|---|"]
    for w in summary["worst"]:
        lat = "" if w["worst_latency_s"] is None else f"{w['worst_latency_s']:.3f}"
        lines.append(f"| {w['scenario']} | `{w['expectation']}` | {w['runs']} | {w['failed']} "
                     f"| {lat} |")
    fails = [r for r in results if not r["passed"]]
    if fails:
        lines += ["", "## Failures and how to reproduce them", ""]
        for r in fails:
            lines.append(f"### {r['name']}, seed {r['seed']}")
            if r.get("known_failure"):
                lines.append(f"Known failure: {r['known_failure']}")
            if r.get("error"):
                lines.append(f"Error: {r['error']}")
            for e in r["expectations"]:
                if e["verdict"] != "pass":
                    lines.append(f"- `{e['text']}`: {e['reason']} "
                                 f"(t = {e['t_broken_s']} s)")
            lines += ["", "```", r["command"], "```", ""]
    mpath = os.path.join(out_dir, "report.md")
    with open(mpath, "w", encoding="utf-8") as f:
        f.write("\n".join(lines) + "\n")
    return mpath, jpath


def main(args: Any, say: Callable[[str], None] = print) -> int:
    """The CLI entry (``hil campaign``); exit 0 iff every run passed, 2 on bad arguments."""
    from hil.cli import _parse_params
    from hil.scenarios import ScenarioError, library_scenarios, load_scenario

    try:
        seeds = parse_seeds(args.seeds)
        params = _parse_params(args.param)
        files = list(args.scenarios) or [str(p) for p in library_scenarios()]
        for f in files:
            load_scenario(f)  # every file checked before anything runs
        if args.jobs is not None and args.jobs < 1:
            raise ValueError(f"--jobs {args.jobs}: at least 1")
    except (ValueError, ScenarioError) as exc:
        print(f"hil campaign: {exc}", file=sys.stderr)
        return 2
    runs = expand(files, seeds, params)
    say(f"hil campaign: {len(runs)} runs ({len(files)} scenarios x {len(seeds)} seeds"
        f"{' x ' + str(len(runs) // (len(files) * len(seeds))) + ' parameter sets' if params else ''})"
        f" on {'dask ' + args.dask if args.dask else str(args.jobs or os.cpu_count()) + ' processes'}")
    results = run_campaign(runs, args.out, jobs=args.jobs, dask=args.dask,
                           one_process=args.one_process)
    md, js = write_report(results, args.out)
    failed = [r for r in results if not r["passed"]]
    say(f"hil campaign: {len(results) - len(failed)}/{len(results)} passed; report: {md}, {js}")
    for r in failed:
        say(f"  FAIL {r['name']} seed {r['seed']}: {r['command']}")
    return 0 if not failed else 1
