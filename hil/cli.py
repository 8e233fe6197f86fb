"""The ``hil`` command: the user-facing entry point of fmu-hil."""

from __future__ import annotations

import argparse
import sys


def _cmd_bench(args: argparse.Namespace) -> int:
    from hil.bench import main

    return main(as_json=args.json, only=args.only)


def _airframe_id(args: argparse.Namespace) -> int | None:
    """``--airframe NAME|ID`` as its SYS_AUTOSTART id; None (after one line on stderr) when
    nothing is called that."""
    from hil.airframes import resolve

    try:
        return resolve(args.airframe).id
    except ValueError as exc:
        print(f"hil {args.command}: {exc}", file=sys.stderr)
        return None


def _cmd_airframes(args: argparse.Namespace) -> int:
    import json

    from hil.airframes import all_airframes

    frames = all_airframes()
    if args.json:
        print(json.dumps([f.as_json() for f in frames], indent=1))
        return 0
    print(f"{'id':>5}  {'name':<16} {'class':<12} {'world':<10} title")
    for f in frames:
        print(f"{f.id:>5}  {f.name:<16} {f.vehicle_class:<12} {f.host.world_model:<10} {f.title}")
    print("fly one: hil run --airframe NAME|ID")
    return 0


def _cmd_run(args: argparse.Namespace) -> int:
    from hil.flight import FlightConfig, main
    from hil.fly import honour_sigint

    airframe = _airframe_id(args)
    if airframe is None:
        return 2
    args.airframe = airframe
    if args.companion_att:
        from hil.companion_system import check_companion_att

        try:
            check_companion_att(airframe)
        except ValueError as exc:
            print(f"hil run: {exc}", file=sys.stderr)
            return 2
    honour_sigint()  # stop on SIGINT even when started in the background by a script
    cfg = FlightConfig(seed=args.seed, out_dir=args.out, airframe=args.airframe,
                       quantum_ns=int(args.quantum_us * 1000), speed=args.speed,
                       mode="local" if args.one_process else "process",
                       timeout_s=args.duration, progress=not args.json,
                       pipeline=not args.no_pipeline, pin_cpus=not args.no_pin,
                       can_escs=args.can_escs, companion=args.companion,
                       companion_att=args.companion_att)
    return main(cfg, as_json=args.json)


def _cmd_log(args: argparse.Namespace) -> int:
    from hil import log_tools

    if args.log_command == "info":
        return log_tools.info_main(args.file)
    return log_tools.plot_main(args.file, args.topics, args.out)


def _cmd_shell(args: argparse.Namespace) -> int:
    from hil import shell_client

    port = args.port
    if port is None and args.board == "companion":
        # the companion's serial console, announced by hil fly --companion
        info = shell_client.discover()
        port = (info or {}).get("companion_console_tcp")
        if port is None:
            print("hil shell: no running emulator with a companion computer found (start one "
                  "with 'hil fly --companion'), or give --port", file=sys.stderr)
            return 1
    board = "companion" if args.board == "companion" else "FMU"
    return shell_client.main(port, args.command, args.timeout, board=board)


def _cmd_fly(args: argparse.Namespace) -> int:
    from hil.fly import main

    airframe = _airframe_id(args)
    if airframe is None:
        return 2
    args.airframe = airframe
    return main(seed=args.seed, speed=args.speed, duration_s=args.duration, out_dir=args.out,
                airframe=args.airframe, keep_safety=args.keep_safety, keep_fram=args.keep_fram,
                fixed_utc=args.fixed_utc, can=args.can, uart=args.uart, param=args.param,
                can_escs=args.can_escs, companion=args.companion or args.ros, ros=args.ros)


def _cmd_params(args: argparse.Namespace) -> int:
    from hil import params_doc

    return params_doc.main(args.out)


def _parse_params(items: list[str] | None) -> dict[str, list[float | int]]:
    """``NAME=V1,V2`` -> {NAME: [V1, V2]}; raises ValueError with the bad item.

    Every name must be declared and every value fit its type (``ParamDef.coerce``: int32, or
    a finite float32), so a bad one is refused here, before any board boots on it."""
    from hil.params_doc import param_def

    out: dict[str, list[float | int]] = {}
    for item in items or []:
        name, sep, values = item.partition("=")
        if not sep or not name or not values:
            raise ValueError(f"--param {item!r}: expected NAME=VALUE[,VALUE...]")
        d = param_def(name)
        if d is None:
            raise ValueError(f"--param {item!r}: unknown parameter {name}")
        vals: list[float | int] = []
        for v in values.split(","):
            try:
                vals.append(int(v))
            except ValueError:
                try:
                    vals.append(float(v))
                except ValueError:
                    raise ValueError(f"--param {item!r}: {v!r} is not a number") from None
            try:
                d.coerce(vals[-1])
            except ValueError as exc:  # ParamError
                raise ValueError(f"--param {item!r}: {exc}") from None
        out[name] = vals
    return out


def _cmd_scenario(args: argparse.Namespace) -> int:
    import json

    from hil.scenarios import ScenarioError, format_table, load_scenario, run_scenario

    try:
        params = {k: v[-1] for k, v in _parse_params(args.param).items()}
        sc = load_scenario(args.file)
    except (ScenarioError, ValueError) as exc:
        print(f"hil scenario: {exc}", file=sys.stderr)
        return 2
    out = args.out or f"out/scenarios/{sc.name}"
    try:
        result = run_scenario(sc, seed=args.seed, out_dir=out,
                              one_process=True if args.one_process else None, params=params,
                              progress=None if args.json else
                              (lambda m: print(f"  {m}", flush=True)))
    except ScenarioError as exc:
        print(f"hil scenario: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(result.as_dict(), indent=1))
    else:
        print(format_table(result))
    return 0 if result.passed else 1


def _cmd_faults(args: argparse.Namespace) -> int:
    import json
    import textwrap

    from hil.faults import CATALOGUE, LOAD_ERRORS

    kinds = sorted(CATALOGUE.values(), key=lambda k: (k.level, k.name))
    if args.json:
        print(json.dumps([{"name": k.name, "level": k.level, "targets": list(k.targets),
                           "params": k.params, "undoable": k.stop is not None, "doc": k.doc}
                          for k in kinds], indent=1))
    else:
        for k in kinds:
            params = ", ".join(f"{p}={v}" for p, v in k.params.items())
            print(f"{k.name}  [{k.level}]  targets: {', '.join(k.targets) or 'none'}"
                  f"{'  params: ' + params if params else ''}"
                  f"{'' if k.stop else '  (cannot be undone)'}")
            print(textwrap.indent(textwrap.fill(k.doc, 92), "    "))
    for mod, err in LOAD_ERRORS.items():
        print(f"hil faults: module {mod} failed to load: {err}", file=sys.stderr)
    return 1 if LOAD_ERRORS else 0


def _cmd_campaign(args: argparse.Namespace) -> int:
    from hil.campaign import main

    return main(args)


def _cmd_hostdrv(args: argparse.Namespace) -> int:
    from hil.hostdrv import main

    return main(args.driver, i2c=args.i2c, spi=args.spi, emulated=args.emulated,
                duration_s=args.duration, print_hz=args.print_hz, seed=args.seed)


def _cmd_native(args: argparse.Namespace) -> int:
    from hil import native

    return native.main(args)


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
    p.add_argument("--airframe", default="4011", metavar="NAME|ID",
                   help="airframe by SYS_AUTOSTART id or name (default 4011, the F450; "
                        "hil airframes lists them)")
    p.add_argument("--one-process", action="store_true",
                   help="run both boards in this process (debugging)")
    p.add_argument("--no-pipeline", action="store_true",
                   help="plain lockstep: a board waits for the orchestrator every quantum "
                        "(default: lookahead, boards hold the next quantum; records between "
                        "boards up to two quanta late)")
    p.add_argument("--no-pin", action="store_true",
                   help="leave CPU placement to the OS (default: the FMU process gets a CPU "
                        "of its own, the orchestrator and the IO share the others)")
    p.add_argument("--can-escs", action="store_true",
                   help="motors on four DroneCAN ESCs (nodes 11-14 on CAN1, UAVCAN_ENABLE 3) "
                        "instead of the IO's PWM outputs")
    p.add_argument("--companion", action="store_true",
                   help="a companion computer (a third board) on the FMU's TELEM2 with the "
                        "uORB bridge (docs/companion.md)")
    p.add_argument("--companion-att", action="store_true",
                   help="the attitude controller runs on the companion, the FMU's as its "
                        "fallback (MC_ATT_IMPL 2; implies --companion)")
    p.add_argument("--json", action="store_true", help="print a machine-readable summary")
    p.set_defaults(func=_cmd_run)

    p = sub.add_parser("fly", help="run paced to the wall clock for ground stations (QGC, MAVSDK)")
    p.add_argument("--speed", type=float, default=1.0, help="times real time (default 1.0)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--duration", type=float, default=None, help="virtual seconds (default: until Ctrl-C)")
    p.add_argument("--out", default="out", help="output folder: log, FRAM, SD card")
    p.add_argument("--airframe", default="4011", metavar="NAME|ID",
                   help="airframe by SYS_AUTOSTART id or name (hil airframes lists them)")
    p.add_argument("--keep-safety", action="store_true",
                   help="do not press the safety switch at boot")
    p.add_argument("--keep-fram", action="store_true",
                   help="keep the FRAM image of the last run (parameters, mission)")
    p.add_argument("--fixed-utc", action="store_true",
                   help="GPS time starts at the fixed epoch of hil run (2024-06-01 12:00 UTC) "
                        "instead of now: same log names and content per seed")
    p.add_argument("--can", action="append", default=[], metavar="BUS=SPEC",
                   help="bind an emulated CAN bus to a python-can bus, e.g. CAN1=socketcan:vcan0, "
                        "CAN1=virtual:chan0, CAN1=slcan:/dev/ttyACM0@115200 (docs/attaching.md)")
    p.add_argument("--uart", action="append", default=[], metavar="NAME=URL",
                   help="bind an emulated UART (gps, telem1, telem2, rc, dsm) to a pyserial URL or "
                        "device, e.g. gps=/dev/ttyUSB0, telem1=socket://10.0.0.5:5760, "
                        "gps=rfc2217://host:4000 (docs/attaching.md)")
    p.add_argument("--can-escs", action="store_true",
                   help="motors on four DroneCAN ESCs (nodes 11-14 on CAN1, UAVCAN_ENABLE 3) "
                        "instead of the IO's PWM outputs")
    p.add_argument("--param", action="append", default=[], metavar="NAME=V",
                   help="parameter override at boot, e.g. UAVCAN_ENABLE=1")
    p.add_argument("--companion", action="store_true",
                   help="a companion computer on TELEM2 with the uORB bridge; its console: "
                        "hil shell --board companion (docs/companion.md)")
    p.add_argument("--ros", action="store_true",
                   help="the companion's topics on ROS 1 (/fmu/out, /fmu/in; implies "
                        "--companion; docs/ros.md)")
    p.set_defaults(func=_cmd_fly)

    p = sub.add_parser("airframes", help="list the airframes hil run --airframe flies")
    p.add_argument("--json", action="store_true",
                   help="a JSON list of objects: id (SYS_AUTOSTART), name, class, ...")
    p.set_defaults(func=_cmd_airframes)

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
    p.add_argument("--board", choices=("fmu", "companion"), default="fmu",
                   help="whose console: the FMU's nsh (default) or the companion computer's "
                        "(hil fly --companion)")
    p.set_defaults(func=_cmd_shell)

    p = sub.add_parser("scenario", help="run a fault scenario and judge its expectations")
    p.add_argument("file", help="scenario YAML file (hil/scenarios/library/ has the shipped ones)")
    p.add_argument("--seed", type=int, default=None, help="override the scenario's seed")
    p.add_argument("--out", default=None, help="output folder (default out/scenarios/NAME)")
    p.add_argument("--param", action="append", metavar="NAME=VALUE",
                   help="override a parameter (repeatable)")
    p.add_argument("--one-process", action="store_true",
                   help="run both boards in this process (same results)")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.set_defaults(func=_cmd_scenario)

    p = sub.add_parser("faults", help="list the fault catalogue")
    p.add_argument("--json", action="store_true", help="print the catalogue as JSON")
    p.set_defaults(func=_cmd_faults)

    p = sub.add_parser("campaign", help="run scenarios x seeds x parameter values in parallel")
    p.add_argument("scenarios", nargs="*",
                   help="scenario files (default: the whole library)")
    p.add_argument("--seeds", default="1", help="seeds: 1-4, 1,3,7 or 5 (default 1)")
    p.add_argument("--param", action="append", metavar="NAME=V1,V2",
                   help="a parameter's values to vary (repeatable: the product is run)")
    p.add_argument("--jobs", type=int, default=None,
                   help="local worker processes (default: CPU count)")
    p.add_argument("--dask", default=None, metavar="ADDRESS|local",
                   help="run on a Dask cluster (scheduler address, or 'local' for a "
                        "LocalCluster)")
    p.add_argument("--one-process", action="store_true",
                   help="each run keeps both boards in its worker process")
    p.add_argument("--out", default="out/campaign", help="output folder (report.md, report.json)")
    p.set_defaults(func=_cmd_campaign)

    p = sub.add_parser("native", help="the compiled tier (mypyc): build, status, clean")
    p.add_argument("native_command", nargs="?", choices=("build", "status", "clean"),
                   default="status")
    p.add_argument("--if-needed", action="store_true",
                   help="build only if the tier is missing or older than the sources")
    p.add_argument("--jobs", type=int, default=None, help="C compiler jobs (default: CPUs)")
    p.set_defaults(func=_cmd_native)

    p = sub.add_parser("hostdrv", help="run one of the FMU's drivers on a host I2C/SPI bus "
                                       "(smbus2/spidev) in real time, printing like listener")
    p.add_argument("driver", choices=("hmc5883", "ms5611"))
    p.add_argument("--i2c", type=int, default=None, metavar="N", help="I2C bus /dev/i2c-N")
    p.add_argument("--spi", default=None, metavar="BUS.CS", help="SPI device /dev/spidevBUS.CS")
    p.add_argument("--emulated", action="store_true",
                   help="the emulated chip behind an smbus2-API object (no hardware needed)")
    p.add_argument("--duration", type=float, default=None, help="seconds (default: until ^C)")
    p.add_argument("--print-hz", type=float, default=1.0,
                   help="print the latest message this often (0: summary only)")
    p.add_argument("--seed", type=int, default=0, help="seed of the emulated chip's noise")
    p.set_defaults(func=_cmd_hostdrv)

    p = sub.add_parser("rosnode", add_help=False, help="a flight-stack module as a native ROS 1 "
                       "node: /fmu/out/<topic> -> module -> /fmu/in/<topic>, time from /clock")
    p.add_argument("rosnode_args", nargs=argparse.REMAINDER)
    p.set_defaults(func=lambda a: __import__("hil.rosnode").rosnode.main(a.rosnode_args))

    p = sub.add_parser("params", help="the parameter reference (markdown) from the metadata")
    p.add_argument("--out", default=None, help="write to this file instead of stdout")
    p.set_defaults(func=_cmd_params)
    for sp in sub.choices.values():
        sp.set_defaults(subparser=sp)  # a wrong option is reported with its command's usage
    return parser


def main(argv: list[str] | None = None) -> int:
    words = sys.argv[1:] if argv is None else list(argv)
    if words[:1] == ["rosnode"]:
        # its own command line (module arguments and options after the module's name, -h)
        return __import__("hil.rosnode").rosnode.main(words[1:])
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if not getattr(args, "func", None):
        args, extra = parser.parse_known_args(["run", *(argv or [])])
    if extra:
        sp = getattr(args, "subparser", parser)
        sp.error(f"unrecognized arguments: {' '.join(extra)}")
    if argv is None and args.command not in ("native", "airframes"):
        # The `hil` command (not a test calling main([...])) runs the compiled tier (hil native
        # build) when it is there and matches the sources; this must come before anything
        # imports a board package. HIL_PURE=1 keeps the sources.
        from hil import native

        native.activate()
    try:
        return args.func(args)
    except KeyboardInterrupt:
        print("hil: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
