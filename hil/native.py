"""The compiled tier: the emulator's hot modules built with mypyc, beside the Python sources.

The boards spend their time in thousands of small calls per virtual second (kernel events,
SPI transfers, chip registers, work items, uORB). CPython runs those at a fixed cost per call
and per attribute; mypyc compiles the same typed source to C extension modules whose classes
keep their attributes in C structs and call each other directly. Nothing changes in what the
code does: the source is the one in this repository, and a test asserts that a compiled and a
pure run of the same flight write byte-identical logs.

Layout. ``hil native build`` copies the board packages into ``<root>/.native/<tag>/`` (a mirror of
the source tree), compiles the modules of :data:`COMPILED` there in place, and writes a
manifest with the hash of every copied file. :func:`activate` puts that mirror first on
``sys.path`` only if the manifest still matches the sources: an edited file makes the tier
stale, and the run falls back to the pure modules (with a notice) until it is rebuilt, so a
change to a ``.py`` file is never silently ignored. ``HIL_PURE=1`` forces the pure modules.

Only the ``hil`` command activates the tier (before it imports a board); tests and library
users import the sources as they are. Board processes are spawned with the parent's
``sys.path``, so they run the same tier as the orchestrator.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
import sysconfig
import time
from pathlib import Path

__all__ = ["COMPILED", "FAST_MODULES", "activate", "build", "native_dir", "status"]

ROOT = Path(__file__).resolve().parent.parent

#: The board packages. The mirror holds them whole (their pure modules import their compiled
#: neighbours) and the freshness digest covers them. ``hil`` and ``bench`` are not mirrored: they
#: import from the sources, and editing them never makes the tier stale.
PACKAGES = ("common", "board", "peripherals", "firmware", "ioproc")

#: The fast modules: the only ones mypyc compiles, chosen by profile and paired measurement
#: (docs/architecture.md, "The compiled tier"). Per-file self time of the pure default flight
#: under cProfile ranked them; compiling the first 49 gave about 85-90 % of what compiling all 154
#: board modules gave (FMU CPU per virtual second, same trace: pure 225 ms, those 176 ms, all
#: 168 ms; the top 21 alone 194 ms) at a third of the build time. Five more since: the sensors
#: module's VehicleAngularVelocity, VehicleIMU and VehicleAcceleration and the RateControl
#: library with its Vector3, split out of two fast modules into PX4's classes and run on the
#: same samples (docs/architecture.md, "Structure restored"). Everything else is ordinary
#: Python that mypyc never sees. A compiled class's bases must be compiled too, and a compiled
#: class that an ordinary module subclasses carries ``allow_interpreted_subclasses=True``
#: (tests/hil/test_native.py checks both).
FAST_MODULES: tuple[str, ...] = (
    # the event kernel, pins, buses and timers: every event of both boards goes through them
    "board/kernel.py", "board/board.py", "board/endpoint.py", "board/gpio.py", "board/timer.py",
    "board/timer_regs.py",
    # the bottom package's quaternions: the estimator and controllers call them per sample
    "common/quaternion.py", "common/units.py", "common/mathlib.py",
    "board/uart.py", "board/spi.py", "board/i2c.py",
    # the register file and the chips read at kHz rates (the IMU's sample engine first)
    "peripherals/regs.py", "peripherals/errors.py", "peripherals/st_spi.py",
    "peripherals/mpu6000/model.py", "peripherals/mpu6000/sampling.py", "peripherals/l3gd20.py",
    "peripherals/lsm303d.py", "peripherals/hmc5883.py", "peripherals/ms5611.py",
    # the platform every module runs on: work queues, uORB, HRT, perf counters
    "firmware/platform/workqueue.py", "firmware/platform/uorb.py", "firmware/platform/hrt.py",
    "firmware/platform/perf.py", "firmware/platform/task.py", "firmware/platform/module.py",
    # the drivers of the sensors above and of the IO link
    "firmware/drivers/device.py", "firmware/drivers/imu/mpu6000.py",
    "firmware/drivers/imu/st_spi_driver.py", "firmware/drivers/imu/l3gd20.py",
    "firmware/drivers/imu/lsm303d.py",
    "firmware/drivers/magnetometer/hmc5883.py", "firmware/drivers/px4io/link.py",
    "firmware/drivers/px4io/driver.py",
    # the modules that run on every IMU sample
    "firmware/modules/sensors/module.py", "firmware/modules/sensors/voter.py",
    "firmware/modules/sensors/vehicle_angular_velocity.py",
    "firmware/modules/sensors/vehicle_imu.py", "firmware/modules/sensors/vehicle_acceleration.py",
    "firmware/modules/ekf2/core.py", "firmware/modules/ekf2/module.py",
    "firmware/modules/mc_rate_control/mc_rate_control.py", "firmware/lib/rate_control.py",
    "firmware/lib/vector3.py",
    "firmware/modules/mc_att_control/mc_att_control.py",
    "firmware/modules/mc_pos_control/mc_pos_control.py", "firmware/modules/logger/logger.py",
    "firmware/modules/mavlink/instance.py",
    # the IO: its link protocol, mixer tick, outputs and RC decoders (per received byte)
    "ioproc/protocol.py", "ioproc/firmware/main.py", "ioproc/firmware/mixer_tick.py",
    "ioproc/firmware/controls.py", "ioproc/pwm_limit.py", "ioproc/mixer/base.py",
    "ioproc/mixer/multirotor.py", "ioproc/rc/common.py", "ioproc/rc/sbus.py", "ioproc/rc/dsm.py",
)
#: What ``hil native build`` compiles (the name the rest of the tree uses).
COMPILED: tuple[str, ...] = FAST_MODULES


def _tag() -> str:
    return f"{sys.implementation.cache_tag}-{sysconfig.get_platform()}"


def native_dir(root: Path = ROOT) -> Path:
    return root / ".native" / _tag()


def _sources(root: Path) -> list[Path]:
    out = []
    for pkg in PACKAGES:
        for p in sorted((root / pkg).rglob("*")):
            if p.is_file() and "__pycache__" not in p.parts and p.suffix not in (".so", ".pyc"):
                out.append(p)
    return out


def _digest(root: Path) -> str:
    h = hashlib.sha256()
    for p in _sources(root):
        h.update(str(p.relative_to(root)).encode())
        h.update(b"\0")
        h.update(p.read_bytes())
        h.update(b"\0")
    h.update(json.dumps(COMPILED).encode())
    return h.hexdigest()


def status(root: Path = ROOT) -> tuple[str, str]:
    """``("fresh" | "stale" | "absent", why)`` for the compiled tier of ``root``."""
    d = native_dir(root)
    manifest = d / "manifest.json"
    if not manifest.exists():
        return "absent", f"no compiled tier at {d} (build it with `hil native build`)"
    try:
        m = json.loads(manifest.read_text())
    except (OSError, ValueError) as exc:
        return "stale", f"unreadable manifest {manifest}: {exc}"
    if m.get("digest") != _digest(root):
        return "stale", ("the sources changed since the compiled tier was built "
                         "(rebuild with `hil native build`)")
    return "fresh", f"compiled tier at {d} ({len(m.get('compiled', []))} modules)"


def activate(root: Path = ROOT, quiet: bool = False) -> bool:
    """Put the compiled tier first on ``sys.path`` if it is fresh; True if it is in use.

    Must run before anything imports a board package. ``HIL_PURE=1`` keeps the sources."""
    if os.environ.get("HIL_PURE", "") not in ("", "0"):
        return False
    state, why = status(root)
    if state != "fresh":
        if state == "stale" and not quiet:
            print(f"hil: running the pure Python modules: {why}", file=sys.stderr)
        return False
    for pkg in PACKAGES:
        mod = sys.modules.get(pkg)
        if mod is not None and not str(getattr(mod, "__file__", "")).startswith(
                str(native_dir(root))):
            if not quiet:
                print(f"hil: running the pure Python modules: {pkg} was imported before the "
                      "compiled tier could be activated", file=sys.stderr)
            return False
    sys.path.insert(0, str(native_dir(root)))
    os.environ["HIL_NATIVE"] = str(native_dir(root))
    return True


def active() -> bool:
    """True if this process runs the compiled tier (set by :func:`activate`, inherited by the
    board processes it spawns)."""
    import board.kernel

    return not str(board.kernel.__file__).endswith(".py")


def clean(root: Path = ROOT) -> bool:
    d = native_dir(root)
    if not d.exists():
        return False
    shutil.rmtree(d)
    return True


def main(args: object) -> int:
    """``hil native build|status|clean``."""
    what = getattr(args, "native_command", None) or "status"
    if what == "status":
        state, why = status()
        print(f"{state}: {why}")
        return 0 if state == "fresh" else 1
    if what == "clean":
        print("removed" if clean() else "nothing to remove", native_dir())
        return 0
    if getattr(args, "if_needed", False) and status()[0] == "fresh":
        print(f"compiled tier is up to date ({native_dir()})")
        return 0
    print(f"compiling {len(COMPILED)} modules with mypyc into {native_dir()} "
          "(about five minutes on two cores) ...", flush=True)
    t0 = time.monotonic()
    try:
        d = build(jobs=getattr(args, "jobs", None))
    except RuntimeError as exc:
        print(f"hil native build: {exc}", file=sys.stderr)
        return 1
    print(f"built in {time.monotonic() - t0:.0f} s: {d}; `hil run` now uses it "
          "(HIL_PURE=1 for the pure modules)")
    return 0


def build(root: Path = ROOT, jobs: int | None = None, verbose: bool = False,
          dest: Path | None = None, opt_level: str | None = None) -> Path:
    """Mirror the packages and compile :data:`COMPILED` there; returns the mirror's path.

    ``dest`` puts the mirror elsewhere than :func:`native_dir` (the test of the tier's
    equivalence builds its own and leaves the user's alone); ``opt_level`` is the C compiler's
    (default ``HIL_NATIVE_OPT`` or 3). The equivalence is about what mypyc makes of the source,
    not about gcc's optimiser, and ``-O0`` compiles quicker."""
    try:
        import mypyc  # noqa: F401
    except ImportError as exc:  # pragma: no cover - mypy is a dependency
        raise RuntimeError("the compiled tier needs mypy (pip install mypy)") from exc
    d = native_dir(root) if dest is None else dest
    work = d.with_name(d.name + ".building")
    shutil.rmtree(work, ignore_errors=True)
    digest = _digest(root)
    for p in _sources(root):
        dst = work / p.relative_to(root)
        dst.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(p, dst)
    t0 = time.monotonic()
    script = (
        "import sys\n"
        "from setuptools import setup\n"
        "from mypyc.build import mypycify\n"
        f"mods = {list(COMPILED)!r}\n"
        f"OPT = {opt_level or os.environ.get('HIL_NATIVE_OPT', '3')!r}\n"
        "setup(name='fmu_hil_native', packages=[], py_modules=[],\n"
        "      ext_modules=mypycify(mods, opt_level=OPT, debug_level='0', separate=True),\n"
        f"      script_args=['-q', 'build_ext', '--inplace', '-j', '{jobs or os.cpu_count() or 1}'])\n"
    )
    (work / "mypy.ini").write_text(
        "[mypy]\nignore_missing_imports = True\nfollow_imports = silent\n")
    proc = subprocess.run([sys.executable, "-c", script], cwd=work, capture_output=not verbose,
                          text=True, check=False)
    if proc.returncode != 0:
        out = (proc.stdout or "") + (proc.stderr or "")
        errors = [ln for ln in out.splitlines() if ": error:" in ln]
        raise RuntimeError("mypyc failed:\n" + "\n".join(errors[:40] or out.splitlines()[-40:]))
    shutil.rmtree(work / "build", ignore_errors=True)
    (work / "manifest.json").write_text(json.dumps(
        {"digest": digest, "compiled": list(COMPILED), "python": sys.version,
         "build_s": round(time.monotonic() - t0, 1)}, indent=1))
    shutil.rmtree(d, ignore_errors=True)
    work.rename(d)
    return d


def check(out_dir: str, seconds: float = 10.0, seed: int = 1) -> dict:
    """Boot the whole system one-process for ``seconds`` of virtual time, logging from boot
    with the raw sensors, and describe the result: which tier ran and the log's SHA-256. Run
    once with the compiled tier and once without, the two must agree (tests/hil/test_native)."""
    from hil.system import SystemConfig, build_system

    scfg = SystemConfig(seed=seed, out_dir=out_dir, mode="local")
    orch, _dev = build_system(scfg)
    with orch:
        orch.run(1_000_000_000)  # rcS has started the logger (armed-only by default)
        for line in ("param set SDLOG_MODE 1", "param set SDLOG_PROFILE 81", "logger stop",
                     "logger start"):
            status, out = orch.call("fmu", "shell", line)
            if status != 0:
                raise RuntimeError(f"nsh {line!r} failed: {out.strip()}")
        orch.run(int((1.0 + seconds) * 1e9))
        orch.call("fmu", "shell", "logger stop")
    logs = sorted(Path(out_dir).rglob("*.ulg"))
    return {"compiled": active(), "kernel": sys.modules["board.kernel"].__file__,
            "logs": [hashlib.sha256(p.read_bytes()).hexdigest() for p in logs],
            "log_bytes": [p.stat().st_size for p in logs]}


if __name__ == "__main__":
    # python -m hil.native OUT_DIR [SECONDS]: the check above, as one JSON line
    print(json.dumps(check(sys.argv[1], float(sys.argv[2]) if len(sys.argv) > 2 else 10.0)))
