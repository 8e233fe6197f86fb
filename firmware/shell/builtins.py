"""Shell built-ins: the language (echo, set, test, sh, exit) and system facts (ver, ps, free).

Every command takes ``(shell, argv)`` and returns its exit status; a bad argument prints an error
and usage lines and returns 1, never raises.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Final

from firmware.system import PathError

if TYPE_CHECKING:
    from firmware.shell.interpreter import Shell

__all__ = ["COMMANDS"]


def cmd_echo(sh: Shell, argv: list[str]) -> int:
    args = argv[1:]
    newline = True
    if args and args[0] == "-n":
        newline, args = False, args[1:]
    sh.write(" ".join(args) + ("\n" if newline else ""))
    return 0


def cmd_set(sh: Shell, argv: list[str]) -> int:
    args = argv[1:]
    if not args:
        for k in sorted(sh.env):
            sh.print(f"{k}={sh.env[k]}")
        return 0
    if args[0] in ("+e", "-e", "+x", "-x"):   # nsh options: errors never stop our scripts
        return 0
    if not args[0].replace("_", "").isalnum() or args[0][0].isdigit():
        sh.error("set", f"invalid variable name '{args[0]}'")
        return 1
    sh.env[args[0]] = " ".join(args[1:])
    return 0


def cmd_unset(sh: Shell, argv: list[str]) -> int:
    if len(argv) < 2:
        return sh.usage(["usage: unset VAR..."])
    for name in argv[1:]:
        sh.env.pop(name, None)
    return 0


def cmd_true(sh: Shell, argv: list[str]) -> int:
    return 0


def cmd_false(sh: Shell, argv: list[str]) -> int:
    return 1


class _TestError(ValueError):
    pass


_INT_OPS: Final = {"-eq": int.__eq__, "-ne": int.__ne__, "-gt": int.__gt__, "-ge": int.__ge__,
            "-lt": int.__lt__, "-le": int.__le__}


def _test(sh: Shell, a: list[str]) -> bool:
    if not a:
        return False
    if "-o" in a:
        i = a.index("-o")
        return _test(sh, a[:i]) or _test(sh, a[i + 1:])
    if "-a" in a[1:]:
        i = a.index("-a", 1)
        return _test(sh, a[:i]) and _test(sh, a[i + 1:])
    if a[0] == "!":
        return not _test(sh, a[1:])
    if len(a) == 1:
        return a[0] != ""
    if len(a) == 2:
        op, x = a
        if op in ("-f", "-d", "-e"):
            try:
                p = sh.system.resolve_path(x)
            except PathError:
                return False
            return p.is_file() if op == "-f" else p.is_dir() if op == "-d" else p.exists()
        if op == "-z":
            return x == ""
        if op == "-n":
            return x != ""
        raise _TestError(f"unknown unary operator '{op}'")
    if len(a) == 3:
        x, op, y = a
        if op in ("=", "=="):
            return x == y
        if op == "!=":
            return x != y
        if op in _INT_OPS:
            try:
                return _INT_OPS[op](int(x), int(y))
            except ValueError:
                raise _TestError(f"integer expected: '{x}' {op} '{y}'") from None
        raise _TestError(f"unknown operator '{op}'")
    raise _TestError(f"too many arguments: {' '.join(a)}")


def cmd_test(sh: Shell, argv: list[str]) -> int:
    args = argv[1:]
    if argv[0] == "[":
        if not args or args[-1] != "]":
            sh.error("[", "missing ']'")
            return 2
        args = args[:-1]
    try:
        return 0 if _test(sh, args) else 1
    except _TestError as exc:
        sh.error(argv[0], str(exc))
        return 2


def cmd_sh(sh: Shell, argv: list[str]) -> int:
    if len(argv) < 2:
        return sh.usage(["usage: sh FILE [args...]"])
    return sh.run_file(argv[1], argv[2:])


def cmd_exit(sh: Shell, argv: list[str]) -> int:
    status = 0
    if len(argv) > 1:
        try:
            status = int(argv[1])
        except ValueError:
            sh.error("exit", f"numeric argument required, got '{argv[1]}'")
            status = 2
    sh.exit_script(status)
    return status  # pragma: no cover - exit_script raises


def cmd_help(sh: Shell, argv: list[str]) -> int:
    if len(argv) > 1:
        name = argv[1]
        if name in sh.commands:
            sh.print(f"{name}: {sh.commands[name].summary}")
            return 0
        if name in sh.system.modules:
            return sh.system.modules.command(name, ["help"])
        sh.error("help", f"no such command '{name}'")
        return 1
    sh.print("Builtin commands:")
    for name in sorted(sh.commands):
        sh.print(f"  {name:<12} {sh.commands[name].summary}")
    mods = sh.system.modules
    sh.print("Modules (NAME start|stop|status|...):")
    for name in mods.names():
        sh.print(f"  {name:<16} {'running' if mods.is_running(name) else ''}".rstrip())
    return 0


_VER_USAGE: Final = ["usage: ver {hw|hwcmp NAME...|git|mcu|all}",
              "  hw          hardware architecture", "  hwcmp NAME  exit 0 if the board is NAME",
              "  git         firmware git hash", "  mcu         microcontroller",
              "  all         everything"]


def cmd_ver(sh: Shell, argv: list[str]) -> int:
    system = sh.system
    if len(argv) < 2:
        return sh.usage(_VER_USAGE)
    what = argv[1]
    mcu = system.board.mcu if system.board is not None else "STM32F427VI"
    lines = {
        "hw": f"HW arch: {system.hw_arch}",
        "git": f"FW git-hash: {system.git_hash or 'not provided by the build'}",
        "mcu": f"MCU: {mcu} (emulated by fmu-hil)",
    }
    if what == "hwcmp":
        if len(argv) < 3:
            return sh.usage(["usage: ver hwcmp NAME [NAME...]"])
        return 0 if any(system.hw_matches(n) for n in argv[2:]) else 1
    if what in lines:
        sh.print(lines[what])
        return 0
    if what == "all":
        sh.print(lines["hw"])
        sh.print(f"HW type: {system.board_name}")
        sh.print(f"FW version: {system.version}")
        sh.print(lines["git"])
        sh.print("OS: none (fmu-hil emulates the NuttX services the flight stack uses)")
        sh.print(lines["mcu"])
        return 0
    sh.error("ver", f"unknown argument '{what}'")
    return sh.usage(_VER_USAGE)


def cmd_reboot(sh: Shell, argv: list[str]) -> int:
    args = argv[1:]
    if any(a not in ("-b",) for a in args):
        sh.error("reboot", f"unknown option '{next(a for a in args if a != '-b')}'")
        return sh.usage(["usage: reboot [-b]", "  -b  reboot into the bootloader"])
    if not sh.system.reboot("-b" in args):
        sh.error("reboot", "not supported: no reboot callback is wired to this system")
        return 1
    return 0


def cmd_dmesg(sh: Shell, argv: list[str]) -> int:
    if len(argv) > 1:
        sh.error("dmesg", f"unknown argument '{argv[1]}'")
        return sh.usage(["usage: dmesg"])
    text = sh.system.platform.dmesg_text()
    if text:
        sh.print(text)
    return 0


def cmd_free(sh: Shell, argv: list[str]) -> int:
    if len(argv) > 1:
        sh.error("free", f"unknown argument '{argv[1]}'")
        return sh.usage(["usage: free"])
    system = sh.system
    p = system.platform
    nodes = p.orb.nodes()
    stored = sum(sum(1 for m in n.buf if m is not None) for n in nodes)
    items = sum(len(q.items) for q in p.wq)
    sh.print("heap: N/A in emulation (the NuttX heap is not modelled; no figures are invented)")
    sh.print("Python-side objects of this board:")
    sh.print(f"  uORB topic instances: {len(nodes)} "
             f"({sum(1 for n in nodes if n.advertised)} advertised), "
             f"messages stored: {stored}")
    sh.print(f"  work queues: {len(p.wq.queues)}, work items: {items}")
    sh.print(f"  perf counters: {len(p.perf.counters)}")
    if system.params is not None:
        sh.print(f"  parameters: {len(system.params.names)} "
                 f"({len(system.params.changed())} changed)")
    sh.print(f"  modules running: {len(system.modules.running())}")
    sh.print(f"  kernel events pending: {len(p.kernel)}")
    sh.print(f"  dmesg lines: {len(p.dmesg)}")
    return 0


def cmd_ps(sh: Shell, argv: list[str]) -> int:
    if len(argv) > 1:
        sh.error("ps", f"unknown argument '{argv[1]}'")
        return sh.usage(["usage: ps"])
    system = sh.system
    sh.print("Modules (no OS tasks are emulated; modules run as work items or generator tasks):")
    running = system.modules.instances()
    if not running:
        sh.print("  (none running)")
    for name, inst in running.items():
        wis = ", ".join(f"{w.name}@{w.wq.name}" for w in inst.work_items) or "-"
        sh.print(f"  {name:<20} {type(inst).__name__:<24} work items: {wis}")
    sh.print("Work queues:")
    sh.print(f"  {'NAME':<24} {'PRI':>4} {'STACK':>6} {'ITEMS':>5} {'QUEUED':>6}")
    for wq in system.platform.wq:
        sh.print(f"  {wq.name:<24} {wq.config.priority:>4} {wq.config.stack_bytes:>6} "
                 f"{len(wq.items):>5} {len(wq):>6}")
        for item in wq.items:
            sched = "queued" if item._queued else (
                f"every {item.interval_us} us" if item.interval_us else
                "scheduled" if item.scheduled else "idle")
            sh.print(f"    {item.name:<22} {sched}")
    return 0


def cmd_ls(sh: Shell, argv: list[str]) -> int:
    path = argv[1] if len(argv) > 1 else "/fs/microsd"
    try:
        p = sh.system.resolve_path(path)
    except PathError as exc:
        sh.error("ls", str(exc))
        return 1
    if p.is_file():
        sh.print(f" {path}")
        return 0
    if not p.is_dir():
        sh.error("ls", f"{path}: no such file or directory")
        return 1
    for child in sorted(p.iterdir()):
        sh.print(f" {child.name}{'/' if child.is_dir() else ''}")
    return 0


def cmd_cat(sh: Shell, argv: list[str]) -> int:
    if len(argv) < 2:
        return sh.usage(["usage: cat FILE..."])
    status = 0
    for path in argv[1:]:
        text = sh.open_text("cat", path)
        if text is None:
            status = 1
        else:
            sh.write(text)
    return status


COMMANDS: Final = {
    "echo": (cmd_echo, "print the arguments"),
    "set": (cmd_set, "set VAR value: set a shell variable (no arguments: list them)"),
    "unset": (cmd_unset, "unset VAR...: remove shell variables"),
    "true": (cmd_true, "exit status 0"),
    "false": (cmd_false, "exit status 1"),
    "test": (cmd_test, "test EXPR: = != == -eq.. -f -d -e -z -n ! -a -o"),
    "[": (cmd_test, "[ EXPR ]: same as test"),
    "sh": (cmd_sh, "sh FILE [args]: run a script"),
    "exit": (cmd_exit, "exit [n]: end the script (or the session)"),
    "help": (cmd_help, "help [COMMAND]: list commands and modules"),
    "ver": (cmd_ver, "ver hw|hwcmp NAME|git|mcu|all: version information"),
    "reboot": (cmd_reboot, "reboot [-b]: reboot the board"),
    "dmesg": (cmd_dmesg, "print the boot and runtime messages"),
    "free": (cmd_free, "memory: heap N/A in emulation, Python-side object counts"),
    "ps": (cmd_ps, "running modules and work queues"),
    "ls": (cmd_ls, "ls [DIR]: list a directory (/etc, /fs/microsd)"),
    "cat": (cmd_cat, "cat FILE...: print files"),
}
