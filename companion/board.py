"""The companion computer as a board: a Linux computer in lockstep with the FMU and the IO.

A Raspberry Pi 4 class computer (:data:`companion.spec.COMPANION_RPI4`) whose FTDI cable
(``/dev/ttyUSB0``) is plugged into the FMU's TELEM2. Its software is this project's firmware
platform, unchanged: its own :class:`~board.kernel.Kernel` (virtual time in lockstep with the
other boards), a :class:`~firmware.platform.Platform` (uORB, work queues, HRT, perf, dmesg), a
:class:`~firmware.platform.params.Params` set kept in a file on its disk, a
:class:`~firmware.system.System` with its own module table (no drivers: the uORB bridge, the
attitude controller, the ROS bridge) and an nsh :class:`~firmware.shell.Shell` on its serial
console. A module written for the FMU starts here as it is: nothing in a module asks which side
it runs on.

Ports (board/wiring.py):

============  ==========  ===============================================================
``telem2``    uart        ``/dev/ttyUSB0``, to the FMU's TELEM2 (COMPANION_WIRES)
``console``   uart        ``/dev/ttyS0``, the serial console (nsh), 115200 8N1
``ros``       value inout records ``(topic, instance, payload_bytes)``: out, what the
                          ``ros_bridge`` module sends to ROS; in, what ROS publishes into the
                          companion's broker (``board.ros_port``, a
                          :class:`firmware.modules.ros_bridge.port.RosPort`)
``reboot``    value out   ``reboot`` on its shell: the orchestrator power-cycles the board
============  ==========  ===============================================================

Start-up: after ``boot_ns`` of virtual time (Linux boots, the service starts) the parameters
load from the disk file, the overrides given to the board (``params=``) are applied and saved
as a user would set them, and the shell runs ``/etc/init.d/rc.companion`` with the board's
``startup`` lines appended (``SystemConfig.companion_att`` adds ``mc_att_control start``).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from board.board import Board
from board.uart import Uart, UartConfig
from companion.disk import PARAMS_FILE, FilePartition
from companion.spec import COMPANION_MODULES, COMPANION_RPI4, CONSOLE_UART
from firmware.modules.ros_bridge.port import expose_ros_port
from firmware.platform import Platform
from firmware.shell.serial_console import SerialConsole

if TYPE_CHECKING:
    from board.specs import BoardSpecData
    from firmware.shell import Shell
    from firmware.system import System

__all__ = ["BOOT_NS", "RC_COMPANION", "CompanionBoard"]

#: Virtual time from power-on until the companion's service starts its script: a trimmed
#: Linux image on a Pi 4 (a full desktop image takes 15-30 s; give ``boot_ns`` to model one).
BOOT_NS = 2_000_000_000
#: the companion's start-up script, as a path of its ROMFS (mounted at /etc, as on the FMU)
RC_COMPANION = "/etc/init.d/rc.companion"
#: an FTDI cable's receive buffer as Linux sees it (the tty layer's 4 KiB flip buffers)
_TTY_RX_BYTES = 4096


class CompanionBoard(Board):
    """The companion computer; its firmware starts by itself ``boot_ns`` after power-on."""

    def __init__(self, name: str = "companion", seed: int = 0, out_dir: str | None = None,
                 startup: tuple[str, ...] = (), params: dict[str, int | float] | None = None,
                 boot_ns: int = BOOT_NS, spec: BoardSpecData = COMPANION_RPI4,
                 modules: dict[str, str] | None = None,
                 host_clock: Callable[[], float] | None = None) -> None:
        super().__init__(name, seed)
        if type(boot_ns) is not int or boot_ns < 0:
            raise ValueError(f"board {name}: boot_ns must be an int >= 0, got {boot_ns!r}")
        k = self.kernel
        self.spec = spec
        #: the computer's disk (a host folder): parameters file, and /fs/microsd for the shell
        self.out_dir = out_dir
        self.startup = tuple(startup)
        self._param_overrides = dict(params or {})
        self._modules = dict(modules if modules is not None else COMPANION_MODULES)
        self._host_clock = host_clock
        self.platform = Platform(k)
        self.system: System | None = None
        self.shell: Shell | None = None
        self._ctl_shell: Shell | None = None
        self.reboot_requested = False
        self.uarts = {u.name: Uart(k, f"{name}.{u.name}", UartConfig(baud=u.baud),
                                   rx_buffer_size=_TTY_RX_BYTES) for u in spec.uarts}
        for u in spec.uarts:
            if u.port is not None:
                self.expose_uart(u.port, self.uarts[u.name])
        # "ros": one value port both ways (the ROS edge, hil/ros, sits on the other end); the
        # ros_bridge module finds it as ``hw.ros_port``
        self.ros_port = expose_ros_port(self)
        self._emit_reboot = self.expose_output("reboot")
        k.call_at(boot_ns, self.boot)

    # -- what firmware sees of the hardware (board.protocols.BoardHardware) ------------------

    @property
    def i2c(self) -> dict[str, Any]:
        return {}

    @property
    def gpio(self) -> Any:
        raise AttributeError(f"board {self.name}: a Linux computer exposes no GPIO here")

    @property
    def adc(self) -> Any:
        return None

    def spi_handle(self, device: str) -> Any:
        raise KeyError(f"board {self.name}: no SPI device {device!r} (the companion has none)")

    def uart_by_device(self, device: str) -> Uart | None:
        """The serial port behind a Linux device name (``/dev/ttyUSB0``), or None."""
        for u in self.spec.uarts:
            if u.device == device:
                return self.uarts[u.name]
        return None

    # -- firmware start-up -----------------------------------------------------------------------

    def params_path(self) -> str | None:
        """The host file holding the parameters (None: no disk, nothing persists)."""
        return os.path.join(self.out_dir, PARAMS_FILE) if self.out_dir is not None else None

    def boot(self) -> None:
        """Linux is up: load the parameters from the disk, apply the overrides, run the script."""
        from firmware.modules import system_params
        from firmware.platform.module import ModuleRegistry
        from firmware.platform.params import MemoryPartition, Params, ParamStorage
        from firmware.shell import Shell
        from firmware.system import System

        p = self.platform
        registry = ModuleRegistry(None, self._modules)
        console = self.uarts[CONSOLE_UART]

        def to_console(text: str) -> None:
            console.write(text.encode())

        sd_root = None
        if self.out_dir is not None:
            os.makedirs(self.out_dir, exist_ok=True)
            sd_root = self.out_dir
        self.system = system = System(p, None, modules=registry, board=self.spec,
                                      sd_root=sd_root, reboot=self._reboot_request,
                                      host_clock=self._host_clock, console=to_console, hw=self)
        path = self.params_path()
        partition: Any = FilePartition(path) if path is not None else MemoryPartition(16384)
        storage = ParamStorage(partition, medium="parameter file")
        params = Params(p, list(system_params.PARAMS) + registry.param_defs(), storage)
        system.params = params
        if self._param_overrides:
            # the system's overrides (hil passes the FMU's): those this computer declares
            params.load()
            skipped = [n for n in self._param_overrides if n not in params]
            if skipped:
                p.info("param", f"{len(skipped)} given parameters not declared here, "
                                f"skipped (first: {skipped[0]})")
            for name, value in self._param_overrides.items():
                if name not in params:
                    continue
                if name == "SYS_AUTOSTART" and params[name] != value:
                    params.set("SYS_AUTOCONFIG", 1, notify=False)  # a new airframe's defaults
                params.set(name, value, notify=False)
            params.save()
        self.shell = shell = Shell(system, output=to_console)
        SerialConsole(console).attach(shell)
        shell.run_file(RC_COMPANION)
        for line in self.startup:
            shell.execute(line)

    def _reboot_request(self, to_bootloader: bool) -> None:
        """``reboot``: the orchestrator power-cycles this board; the disk keeps the parameters."""
        self.platform.warn("reboot", "rebooting in 100 ms")
        self.reboot_requested = True
        k = self.kernel
        k.call_later(100_000_000, lambda: self._emit_reboot(k.now_ns, int(to_bootloader)))

    # -- control calls (tests, tools) -------------------------------------------------------------

    def ctl_shell(self, line: str) -> tuple[int, str]:
        """Run one shell command now; returns (exit status, output)."""
        system = self.system
        if self.shell is None or system is None:
            return 1, "nsh: the companion has not booted yet\n"
        from firmware.shell import Shell

        out: list[str] = []
        if self._ctl_shell is None:
            self._ctl_shell = Shell(system)
        self._ctl_shell.output = out.append
        status = self._ctl_shell.execute(line)
        return status, "".join(out)

    def ctl_booted(self) -> bool:
        return self.system is not None

    def ctl_dmesg(self) -> list[tuple[int, int, str, str]]:
        return list(self.platform.dmesg)

    def ctl_console_lines(self) -> list[str]:
        return list(self.system.console_lines) if self.system is not None else []

    def ctl_topic(self, topic: str, instance: int = 0) -> dict[str, Any] | None:
        """The latest message of a topic instance as a dict (None if never published)."""
        from fmu.board import _plain

        node = self.platform.orb.node(topic, instance)
        msg = node.last
        if msg is None:
            return None
        return _plain(msg) | {"_count": node.publish_count}

    def ctl_param(self, name: str) -> int | float | None:
        system = self.system
        if system is None or system.params is None or name not in system.params:
            return None
        return system.params[name]

    def ctl_modules(self) -> list[str]:
        return self.system.modules.running() if self.system is not None else []
