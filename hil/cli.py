"""The ``hil`` command: the user-facing entry point of fmu-hil."""

from __future__ import annotations

import argparse
import sys


def _cmd_bench(args: argparse.Namespace) -> int:
    from hil.bench import main

    return main(as_json=args.json, only=args.only)


def _cmd_run(args: argparse.Namespace) -> int:
    from hil.demo import main

    return main(seed=args.seed, duration_s=args.duration, as_json=args.json)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="hil", description="Hardware-in-the-loop emulator of the PX4 FMUv2 and its IO board.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    p = sub.add_parser("run", help="run the default emulation (the main job)")
    p.add_argument("--seed", type=int, default=1, help="seed of every noise source (default 1)")
    p.add_argument("--duration", type=float, default=10.0,
                   help="virtual seconds to run (default 10)")
    p.add_argument("--json", action="store_true", help="print a machine-readable summary")
    p.set_defaults(func=_cmd_run)

    p = sub.add_parser("bench", help="measure the speed figures")
    p.add_argument("--json", action="store_true", help="print one JSON object, one key per figure")
    p.add_argument("--only", nargs="+", metavar="KEY", help="run only these figures")
    p.set_defaults(func=_cmd_bench)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        args = parser.parse_args(["run", *(argv or [])])
    try:
        return args.func(args)
    except KeyboardInterrupt:
        print("hil: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
