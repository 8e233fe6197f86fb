"""``hil rosnode MODULE [ARGS...] [--param NAME=VALUE ...] [--name NODE]``: a flight-stack module
as a native ROS 1 node (:mod:`hil.ros.node`).

``hil rosnode mc_att_control`` runs PX4's attitude controller, unchanged, as the node
``/mc_att_control``: it subscribes ``/fmu/out/<topic>`` for every topic the module subscribes,
publishes ``/fmu/in/<topic>`` for every topic it publishes (px4_msgs types generated from
firmware/msg) and keeps time with ``/clock`` when ``/use_sim_time`` is set (the wall clock's
ROS time otherwise). Words that are not ``--param``/``--name`` go to the module's ``start``;
ROS remappings (``__name:=other``, ``__ns:=/uav1``) are rospy's. Parameters: the module's
defaults, then ``--param`` values, then the node's private ROS parameters
(``rosparam set /mc_att_control/MC_ROLL_P 7.0`` before it starts). ``SIGINT``/``SIGTERM`` stop
the module (its status is printed) and the node.
"""

from __future__ import annotations

import re
import signal
import sys
from typing import Any, Final

__all__ = ["main", "parse_args"]

USAGE = ("usage: hil rosnode MODULE [MODULE_ARGS...] [--param NAME=VALUE ...] [--name NODE]\n"
         "  a flight-stack module (hil params lists its parameters) as a ROS 1 node:\n"
         "  /fmu/out/<topic> -> module -> /fmu/in/<topic>, time from /clock (use_sim_time)")


_NAME: Final = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")


class ArgError(ValueError):
    pass


def parse_args(argv: list[str]) -> tuple[str, list[str], dict[str, str], str | None]:
    """(module, module args, {param: value text}, node name); ROS remaps (``a:=b``) skipped."""
    module: str | None = None
    margs: list[str] = []
    params: dict[str, str] = {}
    name: str | None = None
    it = iter(argv)
    for a in it:
        if ":=" in a:
            continue  # rospy's remapping arguments
        if a in ("--param", "--name"):
            v = next(it, None)
            if v is None:
                raise ArgError(f"{a} needs a value")
            if a == "--name":
                name = v
            else:
                pname, eq, val = v.partition("=")
                if not eq or not pname:
                    raise ArgError(f"--param {v!r}: expected NAME=VALUE")
                params[pname] = val
        elif a.startswith("--param="):
            pname, eq, val = a[len("--param="):].partition("=")
            if not eq or not pname:
                raise ArgError(f"{a!r}: expected --param NAME=VALUE")
            params[pname] = val
        elif module is None:
            if a.startswith("-"):
                raise ArgError(f"unknown option {a!r} before the module name")
            module = a
        else:
            margs.append(a)
    if module is None:
        raise ArgError("no module given")
    if not _NAME.match(module):
        raise ArgError(f"{module!r} is not a module name")
    if name is not None and not _NAME.match(name):
        raise ArgError(f"--name {name!r}: a ROS node name is a letter, then letters, digits, _")
    return module, margs, params, name


def _coerce(params: Any, values: dict[str, object]) -> dict[str, object]:
    """Parameter values by their declared type (INT32 / FLOAT), refused if they do not fit."""
    out: dict[str, object] = {}
    for name, text in values.items():
        d = params.defs.get(name)
        if d is None:
            raise ArgError(f"--param {name}: no such parameter")
        try:
            v: object = text
            if isinstance(text, str):
                v = float(text) if d.type == "FLOAT" else int(text, 0)
            out[name] = d.coerce(v)
        except (TypeError, ValueError) as exc:
            raise ArgError(f"--param {name}={text}: {exc}") from None
    return out


def main(argv: list[str]) -> int:
    if not argv or argv[0] in ("-h", "--help"):
        print(USAGE)
        return 0 if argv else 2
    try:
        module, margs, ptext, name = parse_args(argv)
    except ArgError as exc:
        print(f"hil rosnode: {exc}\n{USAGE}", file=sys.stderr)
        return 2
    from firmware.platform.module import ModuleError
    from firmware.platform.params import ParamError
    from hil.ros.node import ModuleHost, RosNode

    try:
        host = ModuleHost(module, margs, name=name or module)
        host_params = _coerce(host.params, dict(ptext))
        for pname, value in host_params.items():
            host.params.set(pname, value, notify=False)
    except (ModuleError, ParamError, ArgError) as exc:
        print(f"hil rosnode: {exc}", file=sys.stderr)
        return 2
    try:
        node = RosNode(host, node_name=name or module)
    except OSError as exc:
        print(f"hil rosnode: {exc}", file=sys.stderr)
        return 1
    rospy = node.rospy
    private = rospy.get_param("~", {})
    if isinstance(private, dict) and private:
        try:
            for pname, value in _coerce(host.params, private).items():
                host.params.set(pname, value, notify=False)
        except ArgError as exc:
            print(f"hil rosnode: private ROS parameter: {exc}", file=sys.stderr)
            return 2

    def stop(signum: int, _frame: Any) -> None:
        node.shutdown()
        rospy.signal_shutdown(signal.Signals(signum).name)

    signal.signal(signal.SIGINT, stop)
    signal.signal(signal.SIGTERM, stop)
    clock = "/clock (use_sim_time)" if node.sim_time else "the wall clock (no use_sim_time)"
    print(f"hil rosnode: {module} as node {rospy.get_name()}, time from {clock}; "
          f"the module starts at the first time value", flush=True)
    started = [False]

    def report_start() -> bool:
        if host.started and not started[0]:
            started[0] = True
            subs, pubs = node.topics()
            print(f"hil rosnode: {module} started at {host.time_us() / 1e6:.3f} s; "
                  f"subscribes {' '.join(subs)}; publishes {' '.join(pubs)}", flush=True)
        return False

    rc = node.run(until=report_start)
    print(node.final_status, end="")
    print(f"hil rosnode: stopped at {host.kernel.now_ns / 1e9:.3f} s; counts "
          f"{dict(host.counts)}, dropped {dict(node.dropped)}", flush=True)
    rospy.signal_shutdown("done")
    return rc
