"""Status commands: ``top``, ``work_queue``, ``perf``, ``uorb`` and ``listener``.

Loads shown by ``top`` are modelled: virtual busy time (bus time plus the CPU time work items
declare) over virtual time elapsed since the previous ``top``. They describe the emulated STM32
and are deterministic. The host-time share (how much of the host's time went into each work
item) needs a host clock injected into the :class:`System`; firmware never reads one itself.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Final

if TYPE_CHECKING:
    from firmware.shell.interpreter import Shell

__all__ = ["COMMANDS"]


def _pct(part: float, whole: float) -> str:
    return f"{100.0 * part / whole:7.2f}" if whole > 0 else "    n/a"


def cmd_top(sh: Shell, argv: list[str]) -> int:
    if argv[1:] not in ([], ["once"]):
        sh.error("top", f"unknown argument '{argv[1]}'")
        return sh.usage(["usage: top [once]",
                         ("  one snapshot per call; rates and loads cover the time since the "
                          "previous top")])
    system = sh.system
    p = system.platform
    now = p.kernel.now_ns
    st = system.shell_state.setdefault("top", {"t_ns": 0, "host_t": None,
                                               # keyed by the item: its queue holds it anyway
                                               # (and compiled items take no weak references)
                                               "items": {},
                                               "queues": {}})
    dt_ns = now - st["t_ns"]
    prof = system.profiler
    host_dt = None
    if prof is not None:
        prof.attach(p)
        host_now = prof.clock()
        host_dt = host_now - (st["host_t"] if st["host_t"] is not None else prof.t0)
        st["host_t"] = host_now
    sh.print(f"top: virtual time {now / 1e9:.6f} s, interval {dt_ns / 1e9:.6f} s "
             "(since the previous top)")
    sh.print("LOAD = modelled busy time / virtual time"
             + ("; HOST = share of host time spent in run()" if prof else ""))
    head = f" {'WORK QUEUE / ITEM':<28} {'RUNS':>8} {'RUNS/s':>8} {'BUSY us':>10} {'LOAD %':>7}"
    sh.print(head + (f" {'HOST %':>7}" if prof else ""))
    total_busy = 0
    total_host = 0.0
    for wq in p.wq:
        q_prev = st["queues"].get(wq.name, (0, 0))
        q_runs = wq.run_count - q_prev[0]
        q_busy = wq.busy_ns_total - q_prev[1]
        st["queues"][wq.name] = (wq.run_count, wq.busy_ns_total)
        total_busy += q_busy
        rows = []
        q_host = 0.0
        for item in wq.items:
            prev = st["items"].get(item, (0, 0, 0.0))
            runs = item.run_count - prev[0]
            busy = item.busy_ns_total - prev[1]
            h = prof.host_s(item) if prof is not None else None
            host = (h - prev[2]) if h is not None else 0.0
            st["items"][item] = (item.run_count, item.busy_ns_total, h or 0.0)
            q_host += host
            rows.append((item.name, runs, busy, host))
        total_host += q_host
        for label, runs, busy, host in [(wq.name, q_runs, q_busy, q_host)] + \
                [("  " + r[0], *r[1:]) for r in rows]:
            rate = f"{runs * 1e9 / dt_ns:8.1f}" if dt_ns > 0 else "     n/a"
            line = (f" {label:<28} {runs:>8} {rate} {busy / 1000:>10.1f} "
                    f"{_pct(busy, dt_ns)}")
            if prof is not None:
                line += f" {_pct(host, host_dt or 0.0)}"
            sh.print(line)
    st["t_ns"] = now
    sh.print(f"total modelled load: {_pct(total_busy, dt_ns).strip()} % of the STM32")
    if prof is None:
        sh.print("host time: not measured (no host clock injected)")
    else:
        sh.print(f"host time in work items: {_pct(total_host, host_dt or 0.0).strip()} % of "
                 f"{(host_dt or 0.0) * 1e3:.1f} ms host time")
    return 0


def cmd_work_queue(sh: Shell, argv: list[str]) -> int:
    if argv[1:] != ["status"]:
        if len(argv) > 1:
            sh.error("work_queue", f"unknown command '{' '.join(argv[1:])}'")
        return sh.usage(["usage: work_queue status"])
    queues = list(sh.system.platform.wq)
    sh.print(f"Work queues: {len(queues)}")
    for wq in queues:
        sh.print(f"{wq.name:<24} prio {wq.config.priority:>4}  items {len(wq.items):>3}  "
                 f"runs {wq.run_count:>8}  busy {wq.busy_ns_total / 1e6:.3f} ms  "
                 f"queued {len(wq)}")
        for item in wq.items:
            iv = f" every {item.interval_us} us" if item.interval_us else ""
            sh.print(f"  |__ {item.name:<20} runs {item.run_count:>8}  "
                     f"busy {item.busy_ns_total / 1e6:.3f} ms{iv}")
    return 0


def cmd_perf(sh: Shell, argv: list[str]) -> int:
    perf = sh.system.platform.perf
    args = argv[1:]
    if args == ["reset"]:
        perf.reset_all()
        sh.print(f"{len(perf.counters)} perf counters reset")
        return 0
    if args:
        sh.error("perf", f"unknown command '{' '.join(args)}'")
        return sh.usage(["usage: perf [reset]", "  (no argument)  print all counters",
                         "  reset           reset all counters"])
    if not perf.counters:
        sh.print("no perf counters")
        return 0
    for pc in perf.counters:
        sh.print(pc.summary())
    return 0


_UORB_USAGE: Final = ["usage: uorb {top [once]|status}",
               "  top     topics with publications and rates since the previous uorb top",
               "  status  every topic instance: advertised, publications, queue, losses"]


def cmd_uorb(sh: Shell, argv: list[str]) -> int:
    args = argv[1:]
    orb = sh.system.platform.orb
    now = sh.system.platform.kernel.now_ns
    if args == ["status"]:
        nodes = orb.nodes()
        sh.print(f"{'TOPIC':<28} {'INST':>4} {'ADV':>3} {'PUBS':>8} {'QUEUE':>5} {'LOST':>6} "
                 f"{'CB':>3}")
        for n in nodes:
            sh.print(f"{n.name:<28} {n.instance:>4} {'yes' if n.advertised else 'no':>3} "
                     f"{n.publish_count:>8} {n.queue_len:>5} {n.lost:>6} {len(n.callbacks):>3}")
        sh.print(f"{len(nodes)} topic instances")
        return 0
    if args in (["top"], ["top", "once"]):
        st = sh.system.shell_state.setdefault("uorb", {"t_ns": 0, "counts": {}})
        dt = now - st["t_ns"]
        sh.print(f"uorb top: interval {dt / 1e9:.6f} s (since the previous uorb top)")
        sh.print(f"{'TOPIC':<28} {'INST':>4} {'#PUB':>8} {'RATE Hz':>9} {'LOST':>6} {'QSIZE':>5}")
        shown = 0
        for n in orb.nodes():
            if not n.advertised and n.publish_count == 0:
                continue
            key = (n.name, n.instance)
            delta = n.publish_count - st["counts"].get(key, 0)
            st["counts"][key] = n.publish_count
            rate = f"{delta * 1e9 / dt:9.1f}" if dt > 0 else "      n/a"
            sh.print(f"{n.name:<28} {n.instance:>4} {n.publish_count:>8} {rate} {n.lost:>6} "
                     f"{n.queue_len:>5}")
            shown += 1
        st["t_ns"] = now
        if not shown:
            sh.print("(no topic published yet)")
        return 0
    if args:
        sh.error("uorb", f"unknown command '{' '.join(args)}'")
    return sh.usage(_UORB_USAGE)


_LISTENER_USAGE: Final = ["usage: listener TOPIC [-n N] [-i INSTANCE]",
                   "  prints the last N messages uORB keeps (1 unless the topic is queued);",
                   "  the shell does not block the emulated CPU, so run it again for newer ones"]


def _value(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.4f}"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, bytes):
        return repr(v.rstrip(b"\0").decode(errors="replace"))
    if isinstance(v, str):
        return repr(v)
    return str(v)


def _print_msg(sh: Shell, msg: Any, now_us: int, indent: str = "    ") -> None:
    for name in msg._fields:
        v = getattr(msg, name)
        if hasattr(v, "_fields"):
            sh.print(f"{indent}{name} ({type(v).__name__}):")
            _print_msg(sh, v, now_us, indent + "    ")
        elif isinstance(v, (list, tuple)) and v and hasattr(v[0], "_fields"):
            for i, sub in enumerate(v):
                sh.print(f"{indent}{name}[{i}] ({type(sub).__name__}):")
                _print_msg(sh, sub, now_us, indent + "    ")
        elif name.startswith("timestamp") and isinstance(v, int) and v:
            sh.print(f"{indent}{name}: {v} ({(now_us - v) / 1000:.3f} ms ago)")
        else:
            sh.print(f"{indent}{name}: {_value(v)}")


def cmd_listener(sh: Shell, argv: list[str]) -> int:
    args = argv[1:]
    if not args or args[0].startswith("-"):
        return sh.usage(_LISTENER_USAGE)
    topic, rest = args[0], args[1:]
    n_msgs, inst = 1, 0
    i = 0
    while i < len(rest):
        opt = rest[i]
        if opt in ("-n", "-i") and i + 1 < len(rest):
            try:
                val = int(rest[i + 1])
            except ValueError:
                sh.error("listener", f"{opt} needs an integer, got '{rest[i + 1]}'")
                return sh.usage(_LISTENER_USAGE)
            if opt == "-n":
                n_msgs = val
            else:
                inst = val
            i += 2
            continue
        sh.error("listener", f"unknown or incomplete option '{opt}'")
        return sh.usage(_LISTENER_USAGE)
    orb = sh.system.platform.orb
    if topic not in orb.registry.topics:
        sh.error("listener", f"unknown topic '{topic}'")
        return 1
    if n_msgs < 1 or not 0 <= inst < 4:
        sh.error("listener", "N must be >= 1 and INSTANCE in 0..3")
        return 1
    node = orb.node(topic, inst)
    if node.generation == 0:
        sh.print(f"listener: {topic} instance {inst}: never published")
        return 1
    gen = node.generation
    avail = min(gen, node.queue_len, n_msgs)
    now_us = sh.system.platform.hrt.absolute_time()
    for g in range(gen - avail + 1, gen + 1):
        msg = node.buf[g % node.queue_len] if node.queue_len > 1 else node.last
        sh.print(f"TOPIC: {topic} instance {inst} #{g}")
        _print_msg(sh, msg, now_us)
    if avail < n_msgs:
        sh.print(f"({avail} of {n_msgs} messages: uORB keeps the last {min(gen, node.queue_len)}"
                 f" of {topic}[{inst}])")
    return 0


COMMANDS: Final = {
    "top": (cmd_top, "top [once]: work items and queues, run counts, modelled load"),
    "work_queue": (cmd_work_queue, "work_queue status: queues and their items"),
    "perf": (cmd_perf, "perf [reset]: performance counters"),
    "uorb": (cmd_uorb, "uorb top|status: topics, publication rates"),
    "listener": (cmd_listener, "listener TOPIC [-n N] [-i I]: print messages of a topic"),
}
