"""The system context of one emulated FMU: what the shell, the startup scripts and modules share.

PX4 reaches these things through globals (the parameter table, the module list, the console's
stdout, the mounted file systems). Here one :class:`System` object per board carries them, so two
boards can run in one process and a test can build a system with a registry of dummy modules.

Paths follow the FMU's file system: ``/etc`` is the ROMFS (a folder of this source tree, read
only by convention) and ``/fs/microsd`` is the emulated SD card (a host directory, or absent).
"""

from __future__ import annotations

import posixpath
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

from firmware.platform.module import ModuleRegistry

if TYPE_CHECKING:
    from board.adc import Adc
    from board.protocols import BoardHardware
    from board.specs import BoardSpecData
    from firmware.drivers.mtd.fram import FramPartition
    from firmware.platform import Platform
    from firmware.platform.params import Params
    from firmware.platform.workqueue import WorkItem

__all__ = ["CONSOLE_LINES", "ROMFS_MOUNT", "SD_MOUNT", "HostProfiler", "PathError", "System"]

ROMFS_MOUNT = "/etc"
SD_MOUNT = "/fs/microsd"
#: lines of background console output kept when no console is attached
CONSOLE_LINES = 500


class PathError(OSError):
    """A path of the FMU file system that does not map to anything (or is not allowed)."""


class HostProfiler:
    """Measures the host time each work item's ``run()`` takes, for ``top``'s host-share column.

    Firmware never reads the host clock on its own: the clock is injected (hil passes
    ``time.perf_counter``). Wrapping ``run`` on the instance keeps the platform untouched; items
    created after :meth:`attach` are measured from the next ``attach`` (``top`` and module
    starts call it).
    """

    def __init__(self, clock: Callable[[], float]) -> None:
        self.clock = clock
        #: host time when profiling began (the first ``top`` interval starts here)
        self.t0 = clock()
        self._acc: dict[int, list[float]] = {}

    def attach(self, platform: Platform) -> int:
        """Wrap every work item not yet wrapped; returns how many were added."""
        added = 0
        for wq in platform.wq:
            for item in wq.items:
                if id(item) in self._acc and item.host_prof is not None:
                    continue
                self._wrap(item)
                added += 1
        return added

    def _wrap(self, item: WorkItem) -> None:
        acc = [0.0]
        orig = item.entry
        clock = self.clock

        def run() -> None:
            t0 = clock()
            try:
                orig()
            finally:
                acc[0] += clock() - t0

        item.entry = run
        item.host_prof = acc
        self._acc[id(item)] = acc

    def host_s(self, item: WorkItem) -> float | None:
        """Host seconds spent in ``item.run`` since it was wrapped, or None if not measured."""
        acc = item.host_prof
        return None if acc is None else acc[0]


class System:
    """Platform, parameters, modules, file system and console of one emulated FMU.

    ``reboot(to_bootloader)`` is called by the shell's ``reboot``; the board (or hil) decides
    what a reboot means. ``host_clock`` enables the host-time column of ``top``.

    ``hw`` is the board's hardware as firmware sees it (:class:`board.protocols.BoardHardware`:
    buses, pins, ADC, spec), from which driver modules build their drivers; None for a system
    without a board (a test's registry of dummy modules). ``adc`` is the board's ADC (the
    battery monitor's), ``hw.adc`` unless given.
    """

    def __init__(self, platform: Platform, params: Params | None = None, *,
                 modules: ModuleRegistry | Mapping[str, Any] | None = None,
                 board: BoardSpecData | None = None,
                 board_name: str | None = None,
                 sd_root: str | Path | None = None,
                 romfs_root: str | Path | None = None,
                 reboot: Callable[[bool], None] | None = None,
                 host_clock: Callable[[], float] | None = None,
                 version: str = "fmu-hil 0.1.0",
                 git_hash: str | None = None,
                 console: Callable[[str], None] | None = None,
                 hw: BoardHardware | None = None,
                 adc: Adc | None = None) -> None:
        from firmware import romfs

        self.platform = platform
        self.params = params
        self.board = board
        self.hw = hw
        self.adc = adc if adc is not None else (hw.adc if hw is not None else None)
        #: the FRAM's waypoint partition, when the board has one (dataman keeps missions there)
        self.waypoints_partition: FramPartition | None = None
        self.board_name = board_name or (board.name if board is not None else "px4_fmu-v2")
        self.sd_root = Path(sd_root) if sd_root is not None else None
        self.romfs_root = Path(romfs_root) if romfs_root is not None else romfs.ROMFS_ROOT
        self.reboot_callback = reboot
        self.host_clock = host_clock
        self.profiler = HostProfiler(host_clock) if host_clock is not None else None
        self.version = version
        self.git_hash = git_hash
        #: the writer of background output (a module printing outside any shell command)
        self.console = console
        self.console_lines: list[str] = []
        self._writers: list[Callable[[str], None]] = []
        #: per-command state kept between calls (top and uorb top intervals)
        self.shell_state: dict[str, Any] = {}
        if isinstance(modules, ModuleRegistry):
            self.modules = modules
            modules.system = self
        else:
            self.modules = ModuleRegistry(self, modules)
        self.reboot_requests = 0

    # -- identity ------------------------------------------------------------------------------

    @property
    def hw_arch(self) -> str:
        """PX4's hardware name (``PX4_FMU_V2``), as ``ver hw`` prints and ``ver hwcmp`` tests."""
        return self.board_name.upper().replace("-", "_")

    def hw_matches(self, name: str) -> bool:
        """True for this board's name in any of PX4's spellings (px4_fmu-v2, PX4FMU_V2, ...)."""
        want = name.upper().replace("-", "_")
        arch = self.hw_arch
        return want in (arch, arch.replace("PX4_", "PX4", 1), self.board_name.upper())

    # -- console --------------------------------------------------------------------------------

    @contextmanager
    def redirect(self, writer: Callable[[str], None]) -> Iterator[None]:
        """Send :meth:`write` output to ``writer`` meanwhile (a shell running a command)."""
        self._writers.append(writer)
        try:
            yield
        finally:
            self._writers.pop()

    def write(self, text: str) -> None:
        """Write to the console of the command being run, else to the background console."""
        if self._writers:
            self._writers[-1](text)
            return
        self.write_background(text)

    def write_background(self, text: str) -> None:
        """Write to the board's console (or keep the last lines when none is attached)."""
        if self.console is not None:
            self.console(text)
            return
        self.console_lines.extend(text.splitlines())
        if len(self.console_lines) > CONSOLE_LINES:
            del self.console_lines[: len(self.console_lines) - CONSOLE_LINES]

    def print(self, text: str = "") -> None:
        self.write(text + "\n")

    # -- file system ----------------------------------------------------------------------------

    def resolve_path(self, path: str) -> Path:
        """The host path behind an FMU path: ``/etc/...`` (ROMFS) or ``/fs/microsd/...``.

        A relative path is taken relative to the SD card, where PX4 users keep their files.
        ``..`` cannot leave a mount point.
        """
        p = path if path.startswith("/") else f"{SD_MOUNT}/{path}"
        p = posixpath.normpath(p)
        for mount, root, what in ((ROMFS_MOUNT, self.romfs_root, "ROMFS"),
                                  (SD_MOUNT, self.sd_root, "SD card")):
            if p == mount or p.startswith(mount + "/"):
                if root is None:
                    raise PathError(f"{path}: no {what} present")
                rel = p[len(mount):].lstrip("/")
                return Path(root) / rel if rel else Path(root)
        raise PathError(f"{path}: no such file or directory (only {ROMFS_MOUNT} and "
                        f"{SD_MOUNT} are mounted)")

    def is_file(self, path: str) -> bool:
        try:
            return self.resolve_path(path).is_file()
        except PathError:
            return False

    # -- reboot ----------------------------------------------------------------------------------

    def reboot(self, to_bootloader: bool = False) -> bool:
        """Ask the board to reboot; False when nothing is wired to do it."""
        self.reboot_requests += 1
        if self.reboot_callback is None:
            return False
        self.reboot_callback(to_bootloader)
        return True
