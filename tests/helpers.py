"""Helpers that more than one test module uses: a watchdog that turns a hang into a failure,
and a small parameter set for the parameter tests and fuzz targets.

They live here, with public names, so that no test module imports another's privates.
"""

from __future__ import annotations

import contextlib
import signal
from typing import Iterator

from firmware.platform.params import ParamDef

__all__ = ["PARAM_DEFS", "ctrl_c_reaches_child", "terminates"]

#: A few parameters of both types, with a range, a unit and an enumeration: enough to reach
#: every path of the parameter store without booting a board.
PARAM_DEFS = [
    ParamDef("SYS_AUTOSTART", "INT32", 0, group="System", short="Airframe",
             reboot_required=True),
    ParamDef("MC_ROLL_P", "FLOAT", 6.5, min=0.0, max=12.0, group="MC Attitude",
             short="Roll P gain", decimals=2),
    ParamDef("MC_PITCH_P", "FLOAT", 6.5, min=0.0, max=12.0, group="MC Attitude"),
    ParamDef("COM_RC_LOSS_T", "FLOAT", 0.5, unit="s", group="Commander"),
    ParamDef("COM_ARM_WO_GPS", "INT32", 1, values={0: "Deny", 1: "Allow"}, group="Commander"),
]


@contextlib.contextmanager
def terminates(seconds: float = 2.0) -> Iterator[None]:
    """Fail with TimeoutError (instead of hanging the suite) if the block runs longer than
    ``seconds`` of wall time: a decoder or loader that loops is the worst kind of bug here.

    Uses SIGALRM, so it works in the main thread of the test process only (as pytest runs)."""
    def expire(_sig: int, _frame: object) -> None:
        raise TimeoutError(f"still running after {seconds} s")
    old = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def ctrl_c_reaches_child() -> None:
    """``preexec_fn`` for a child that a test stops with SIGINT (the user's Ctrl-C).

    ``make test`` run as a background job of a non-interactive shell (CI scripts, ``cmd &``)
    starts with SIGINT ignored; pytest and its xdist workers inherit that, and so would the
    child, which then never stops on SIGINT (Python installs its KeyboardInterrupt handler only
    where SIGINT was not ignored)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


def shared_across_workers(tmp_path_factory, worker_id: str, key: str, make):
    """``make()``'s result (picklable), computed once per test session even when pytest-xdist
    spreads a module's tests over workers: a module fixture is set up on each worker that runs
    one of its tests, and an end-to-end flight costs minutes of CPU. The first worker computes
    under a file lock in the session's shared temporary folder and leaves the result there; the
    others read it (pytest-xdist's documented pattern for session-wide fixtures)."""
    import fcntl
    import pickle

    if worker_id == "master":                      # no xdist: compute here
        return make()
    shared = tmp_path_factory.getbasetemp().parent
    result_file = shared / f"{key}.pickle"
    with open(shared / f"{key}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)           # released when the file closes
        if result_file.exists():
            return pickle.loads(result_file.read_bytes())
        result = make()
        result_file.write_bytes(pickle.dumps(result))
        return result


def booted_fmu(params: dict, boot_ns: int = 1_500_000_000):
    """An in-process FMU board booted through rcS with ``params`` (no orchestrator, no IO):
    for module tests that stand in for the rest of the stack by publishing its topics."""
    from fmu.board import FmuV2Board

    board = FmuV2Board(seed=1, sd_root=None, params=params)
    board.kernel.run(boot_ns)
    return board


def publish(board, topic: str, **fields) -> None:
    """Publish one ``topic`` message on ``board``'s uORB, stamped now, as the module that owns
    the topic would (a test standing in for a controller or a driver)."""
    orb = board.platform.orb
    msg = orb.new(topic, **fields)
    msg.timestamp = board.kernel.now_ns // 1000
    orb.advertise(topic).publish(msg)


def fly_in(tmp_path_factory, name: str, **config) -> dict:
    """``hil.flight.fly`` quietly (no progress, no plot) in a fresh folder ``name`` of the
    session's temporary tree: one end-to-end flight's summary.

    Both boards run in the test's process (``mode="local"``, as the scenarios do): under
    pytest-xdist both cores are busy anyway, and the board processes' exchanges cost a quarter
    of a flight's CPU (plane, 45 s of seed 2: 13.4 s local, 17.7 s in processes, measured).
    Nor are CPUs pinned: ``hil run`` gives its FMU a CPU of its own, which pays when one
    flight has the machine. Results depend on neither (docs/architecture.md, Lockstep)."""
    from hil.flight import FlightConfig, fly

    out = tmp_path_factory.mktemp(name)
    config.setdefault("pin_cpus", False)
    config.setdefault("mode", "local")
    return fly(FlightConfig(out_dir=str(out), progress=False, plot=False, **config))


def same_log_start(full_log: str, short_log: str, min_bytes: int = 100_000) -> bool:
    """True if the ULog of a run stopped early (``FlightConfig.stop_after_s``) is, byte for
    byte, the start of the whole run's ULog of the same seed: the logger writes one stream,
    and stopping the boards only cuts it short. That checks a seed's determinism for the cost
    of the shorter run, not of a second whole flight."""
    with open(short_log, "rb") as f:
        short = f.read()
    with open(full_log, "rb") as f:
        full = f.read(len(short))
    return len(short) >= min_bytes and full == short
