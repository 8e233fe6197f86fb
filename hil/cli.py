"""The ``hil`` command: the user-facing entry point of fmu-hil."""

from __future__ import annotations

import argparse
import sys


def _cmd_bench(args: argparse.Namespace) -> int:
    from hil.bench import main

    return main(as_json=args.json, only=args.only)


def _cmd_run(args: argparse.Namespace) -> int:
    from hil.flight import FlightConfig, main

    cfg = FlightConfig(seed=args.seed, out_dir=args.out, airframe=args.airframe,
                       quantum_ns=int(args.quantum_us * 1000), speed=args.speed,
                       mode="local" if args.one_process else "process",
                       timeout_s=args.duration, progress=not args.json)
    return main(cfg, as_json=args.json)


def _cmd_log(args: argparse.Namespace) -> int:
    from hil import log_tools

    if args.log_command == "info":
        return log_tools.info_main(args.file)
    return log_tools.plot_main(args.file, args.topics, args.out)


def _cmd_shell(args: argparse.Namespace) -> int:
    from hil import shell_client

    return shell_client.main(args.port, args.command, args.timeout)


def _cmd_fly(args: argparse.Namespace) -> int:
    from hil.fly import main

    return main(seed=args.seed, speed=args.speed, duration_s=args.duration, out_dir=args.out,
                airframe=args.airframe, keep_safety=args.keep_safety, keep_fram=args.keep_fram)


def _cmd_params(args: argparse.Namespace) -> int:
    from hil import params_doc

    return params_doc.main(args.out)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="hil", description="Hardware-in-the-loop emulator of the PX4 FMUv2 and its IO board.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    p = sub.add_parser("run", help="fly the default mission (the main job)")
    p.add_argument("--seed", type=int, default=1, help="seed of every noise source (default 1)")
    p.add_argument("--duration", type=float, default=240.0,
                   help="virtual seconds the flight may take before it counts as failed")
    p.add_argument("--speed", type=float, default=None,
                   help="pace to the wall clock times this factor (default: as fast as possible)")
    p.add_argument("--quantum-us", type=float, default=500.0,
                   help="lockstep quantum in microseconds (default 500, hil.system)")
    p.add_argument("--out", default="out", help="output folder: log, plot, FRAM, SD card")
    p.add_argument("--airframe", type=int, default=4011, help="SYS_AUTOSTART (default 4011, F450)")
    p.add_argument("--one-process", action="store_true",
                   help="run both boards in this process (debugging)")
    p.add_argument("--json", action="store_true", help="print a machine-readable summary")
    p.set_defaults(func=_cmd_run)

    p = sub.add_parser("fly", help="run paced to the wall clock for ground stations (QGC, MAVSDK)")
    p.add_argument("--speed", type=float, default=1.0, help="times real time (default 1.0)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--duration", type=float, default=None, help="virtual seconds (default: until Ctrl-C)")
    p.add_argument("--out", default="out", help="output folder: log, FRAM, SD card")
    p.add_argument("--airframe", type=int, default=4011)
    p.add_argument("--keep-safety", action="store_true",
                   help="do not press the safety switch at boot")
    p.add_argument("--keep-fram", action="store_true",
                   help="keep the FRAM image of the last run (parameters, mission)")
    p.set_defaults(func=_cmd_fly)

    p = sub.add_parser("bench", help="measure the speed figures")
    p.add_argument("--json", action="store_true", help="print one JSON object, one key per figure")
    p.add_argument("--only", nargs="+", metavar="KEY", help="run only these figures")
    p.set_defaults(func=_cmd_bench)

    p = sub.add_parser("log", help="inspect and plot ULog files")
    logsub = p.add_subparsers(dest="log_command", metavar="info|plot", required=True)
    q = logsub.add_parser("info", help="summary of a ULog file (topics, counts, messages)")
    q.add_argument("file")
    q = logsub.add_parser("plot", help="PNG plots of a ULog file")
    q.add_argument("file")
    q.add_argument("topics", nargs="*", help="extra topics to plot")
    q.add_argument("--out", default=None, help="output folder (default: next to the log)")
    p.set_defaults(func=_cmd_log)

    p = sub.add_parser("shell", help="attach to the nsh console of a running emulator")
    p.add_argument("--port", type=int, default=None,
                   help="console TCP port (default: the newest running hil)")
    p.add_argument("-c", dest="command", default=None, help="run one command and exit")
    p.add_argument("--timeout", type=float, default=30.0, help="seconds to wait for a reply")
    p.set_defaults(func=_cmd_shell)

    p = sub.add_parser("params", help="the parameter reference (markdown) from the metadata")
    p.add_argument("--out", default=None, help="write to this file instead of stdout")
    p.set_defaults(func=_cmd_params)
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
