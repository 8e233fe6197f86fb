"""``param``: show, set, compare, save and load the board's parameters from the shell.

``param compare`` and ``param greater`` answer only through their exit status, so startup
scripts can branch on parameters (``if param compare SYS_AUTOSTART 4001``). Files of ``param
export``/``import`` are QGroundControl ``.params`` files on the emulated SD card.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from firmware.platform.bson import BsonError
from firmware.platform.params import ParamError, export_qgc, import_qgc
from firmware.system import PathError

if TYPE_CHECKING:
    from firmware.platform.params import Params
    from firmware.shell.interpreter import Shell

__all__ = ["COMMANDS"]

USAGE = [
    "usage: param <command> [arguments...]",
    "  show [-c] [PATTERN]       list parameters (-c: only changed; PATTERN: prefix or glob)",
    "  get NAME                  print a value",
    "  set NAME VALUE            set a value",
    "  compare NAME VALUE...     exit 0 if the value equals one of VALUEs",
    "  greater NAME VALUE        exit 0 if the value is greater than VALUE",
    "  reset NAME...             back to the default",
    "  reset_all [EXCLUDE...]    all back to defaults (except glob patterns)",
    "  save                      save to storage (FRAM)",
    "  load [FILE]               load from storage, or from a PX4 parameter file (BSON)",
    "  status                    counts and storage",
    "  export FILE               write a QGC .params file (relative to /fs/microsd)",
    "  import FILE               read a QGC .params file",
]


def _fmt(params: Params, name: str) -> str:
    v = params.values[name]
    return f"{v:.4f}" if params.defs[name].type == "FLOAT" else str(v)


def _parse(params: Params, name: str, text: str) -> int | float:
    """A typed value from text: INT32 takes integers (0x.. too), FLOAT any number that is
    finite as a float32; anything else is a ParamError saying why (``ParamDef.coerce``)."""
    d = params.defs[name]
    try:
        value: int | float = int(text, 0) if d.type == "INT32" else float(text)
    except ValueError:
        kind = "an integer" if d.type == "INT32" else "a float"
        raise ParamError(f"{name} is {kind} parameter, got '{text}'") from None
    return d.coerce(value)


def _show(sh: Shell, params: Params, args: list[str]) -> int:
    changed_only = False
    pattern = None
    for a in args:
        if a == "-c":
            changed_only = True
        elif a == "-a":
            pass
        elif a.startswith("-"):
            sh.error("param show", f"unknown option '{a}'")
            return sh.usage(USAGE)
        elif pattern is None:
            pattern = a
        else:
            sh.error("param show", "too many arguments")
            return sh.usage(USAGE)
    names = params.match(pattern)
    if changed_only:
        changed = set(params.changed())
        names = [n for n in names if n in changed]
    sh.print("Symbols: * = changed from default")
    changed = set(params.changed())
    for n in names:
        mark = "*" if n in changed else " "
        sh.print(f"{mark} {n} [{params.index(n)}]: {_fmt(params, n)}")
    sh.print(f"{len(names)}/{len(params.names)} parameters shown")
    return 0


def _need(sh: Shell, params: Params, sub: str, name: str) -> bool:
    if name not in params:
        sh.error(f"param {sub}", f"parameter {name} not found")
        return False
    return True


def _file(sh: Shell, sub: str, path: str):
    try:
        return sh.system.resolve_path(path)
    except PathError as exc:
        sh.error(f"param {sub}", str(exc))
        return None


def _load_file(sh: Shell, params: Params, name: str) -> int:
    """``param load FILE``: a PX4 parameter file (bare BSON, e.g. a real board's FRAM
    parameters); one that does not decode changes nothing."""
    path = _file(sh, "load", name)
    if path is None:
        return 1
    try:
        data = path.read_bytes()
    except OSError as exc:
        sh.error("param load", f"{name}: {exc.strerror or exc}")
        return 1
    try:
        loaded, skipped = params.load_document(data, name)
    except BsonError as exc:
        sh.error("param load", f"{name}: not a PX4 parameter file ({exc}); nothing changed")
        return 1
    sh.print(f"loaded {loaded} parameters from {name}"
             + (f", {skipped} skipped (see dmesg)" if skipped else ""))
    return 0


def cmd_param(sh: Shell, argv: list[str]) -> int:
    params = sh.system.params
    if len(argv) < 2:
        return sh.usage(USAGE)
    sub, args = argv[1], argv[2:]
    if params is None:
        sh.error("param", "no parameters on this system")
        return 1
    nargs = {"get": 1, "set": 2, "greater": 2, "export": 1, "import": 1, "save": 0, "load": 0,
             "status": 0}
    if sub in nargs and len(args) != nargs[sub] and not (sub == "set" and len(args) == 3) \
            and not (sub == "load" and len(args) == 1):
        sh.error("param", f"{sub}: expected {nargs[sub]} argument(s), got {len(args)}")
        return sh.usage(USAGE)
    if sub == "show":
        return _show(sh, params, args)
    if sub == "get":
        if not _need(sh, params, sub, args[0]):
            return 1
        sh.print(_fmt(params, args[0]))
        return 0
    if sub == "set":
        name = args[0]
        if not _need(sh, params, sub, name):
            return 1
        try:
            value = _parse(params, name, args[1])
            old = _fmt(params, name)
            params.set(name, value)
        except ParamError as exc:
            sh.error("param set", str(exc))
            return 1
        d = params.defs[name]
        if not d.in_range(params.values[name]):
            sh.print(f"WARN: {name} = {_fmt(params, name)} is outside its range "
                     f"[{d.min}, {d.max}]")
        sh.print(f"{name}: curr: {old} -> new: {_fmt(params, name)}")
        return 0
    if sub in ("compare", "greater"):
        if len(args) < 2 or (sub == "greater" and len(args) != 2):
            return sh.usage(USAGE)
        name = args[0]
        if not _need(sh, params, sub, name):
            return 1
        cur = params.values[name]
        try:
            values = [_parse(params, name, a) for a in args[1:]]
        except ParamError as exc:
            sh.error(f"param {sub}", str(exc))
            return 1
        if sub == "compare":
            return 0 if any(cur == v for v in values) else 1
        return 0 if cur > values[0] else 1
    if sub == "reset":
        if not args:
            return sh.usage(USAGE)
        status = 0
        for name in args:
            if _need(sh, params, sub, name):
                params.reset(name)
            else:
                status = 1
        return status
    if sub == "reset_all":
        n = params.reset_all(exclude=args)
        sh.print(f"{n} parameters reset to defaults")
        return 0
    if sub == "load" and args:
        return _load_file(sh, params, args[0])
    if sub in ("save", "load"):
        if params.storage is None:
            sh.error(f"param {sub}", "no parameter storage (FRAM not wired)")
            return 1
        ok = params.save() if sub == "save" else params.load()
        if not ok:
            sh.error(f"param {sub}", "failed (see dmesg)")
        return 0 if ok else 1
    if sub == "status":
        sh.print(f"parameters: {len(params.names)} declared, {len(params.changed())} changed")
        sh.print(f"sets: {params.set_count}, saves: {params.save_count}")
        st = params.storage
        sh.print("storage: none" if st is None else
                 f"storage: FRAM, 2 slots of {st.slot_size} bytes, last save #{st.sequence}"
                 f" in slot {st.last_slot}")
        return 0
    if sub == "export":
        path = _file(sh, sub, args[0])
        if path is None:
            return 1
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(export_qgc(params))
        except OSError as exc:
            sh.error("param export", f"{args[0]}: {exc.strerror or exc}")
            return 1
        sh.print(f"exported {len(params.names)} parameters to {args[0]}")
        return 0
    if sub == "import":
        path = _file(sh, sub, args[0])
        if path is None:
            return 1
        try:
            text = sh.read_text(path)
        except OSError as exc:
            sh.error("param import", f"{args[0]}: {exc.strerror or exc}")
            return 1
        count, problems = import_qgc(params, text)
        for p in problems:
            sh.error("param import", f"{args[0]}: {p}")
        sh.print(f"imported {count} parameters from {args[0]}")
        return 1 if problems else 0
    sh.error("param", f"unknown command '{sub}'")
    return sh.usage(USAGE)


COMMANDS = {"param": (cmd_param, "param show|get|set|compare|greater|save|load|export|...")}
