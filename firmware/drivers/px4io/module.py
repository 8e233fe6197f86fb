"""``px4io``: the shell face of the IO driver (start options, status, custom commands).

The UART comes from the board through the system (``system.hw.uarts``, or ``system.uarts``):
``-d`` picks one by USART name, NuttX device or role (default the board's ``io_link``, USART6 =
/dev/ttyS4 on FMUv2).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, ClassVar, Final

from firmware.drivers.px4io.driver import Px4ioDriver
from firmware.drivers.px4io.params import PARAMS
from firmware.platform.module import ModuleBase, ModuleError, UsageError
from ioproc.protocol import FORCE_SAFETY_MAGIC, PageNo, Setup

if TYPE_CHECKING:
    from board.uart import Uart
    from firmware.platform.params import ParamDef
    from firmware.system import System

__all__ = ["Px4ioModule"]

DEFAULT_DEVICE: Final = "io_link"
#: E14's rc scripts ran ``px4io limit 400`` for multicopters; this tree's rcS does not, so the
#: driver starts with that limit.
DEFAULT_UPDATE_RATE_HZ: Final = 400


class Px4ioModule(ModuleBase):
    """The FMU driver of the PX4IO coprocessor (E14 protocol 4, mixer on the IO)."""

    NAME: ClassVar[str] = "px4io"
    DESCRIPTION: ClassVar[str] = "FMU driver of the PX4IO safety coprocessor (protocol 4)"
    USAGE: ClassVar[tuple[str, ...]] = (
        "start [-d DEVICE] [-m MIXER]  DEVICE: USART6, /dev/ttyS4 or io_link (default)",
        "                              MIXER: a file of /etc/mixers (quad_x.main.mix) or a path",
        "safety_off                    force the IO's safety off (SETUP 12 = 22027)",
        "safety_on                     force the IO's safety on (SETUP 14 = 22027)",
        "limit <Hz>                    actuator_controls_0 update limit (E14: 2..100 ms)",
        "mixer <file>                  upload a mixer to the IO",
        "recovery                      set INAIR_RESTART_OK (allow an in-air FMU restart)",
        "debug <level>                 IO console debug level (SETUP 9)",
    )
    PARAMS: ClassVar[tuple[ParamDef, ...]] = PARAMS

    def __init__(self, system: System, args: Sequence[str] = ()) -> None:
        super().__init__(system, args)
        self.device = DEFAULT_DEVICE
        self.mixer: str | None = None
        self.driver: Px4ioDriver | None = None

    @classmethod
    def instantiate(cls, system: System, args: Sequence[str]) -> ModuleBase:
        inst = cls(system, args)
        it = iter(args)
        for arg in it:
            if arg not in ("-d", "-m"):
                raise UsageError(f"unknown option {arg}")
            value = next(it, None)
            if value is None:
                raise UsageError(f"option {arg} needs a value")
            if arg == "-d":
                inst.device = value
            else:
                inst.mixer = value
        return inst

    # -- life cycle ---------------------------------------------------------------------------

    def _start(self) -> None:
        uart = self._find_uart(self.device)
        self.driver = Px4ioDriver(self, uart, self.mixer, DEFAULT_UPDATE_RATE_HZ)
        self.driver.start()

    def _stop(self) -> None:
        if self.driver is not None:
            self.driver.stop()

    def init_failed(self) -> None:
        """Called by the task when the IO was refused: stop as ``px4io start`` would fail."""
        k = self.platform.kernel
        k.call_at(k.now_ns, self._stop_if_running)

    def _stop_if_running(self) -> None:
        if self.running:
            self.stop()

    def _find_uart(self, device: str) -> Uart:
        """The UART named ``device`` (USART6), by NuttX device (/dev/ttyS4) or role (io_link).

        The board hands its UARTs to the system as ``system.hw.uarts`` (FmuV2Board) or
        ``system.uarts`` (tests); a driver never builds its own.
        """
        hw = getattr(self.system, "hw", None)
        uarts: dict[str, Any] | None = getattr(self.system, "uarts", None) or \
            getattr(hw, "uarts", None)
        if not uarts:
            raise ModuleError(f"{self.name}: this system exposes no UARTs (system.hw.uarts)")
        if device in uarts:
            return uarts[device]
        from board.specs import FMU_V2

        spec = self.system.board or getattr(hw, "spec", None) or FMU_V2
        for u in spec.uarts:
            if device in (u.device, u.role) and u.name in uarts:
                return uarts[u.name]
        raise ModuleError(f"{self.name}: no UART {device!r} (have {', '.join(sorted(uarts))})")

    # -- status and commands ------------------------------------------------------------------

    def status_lines(self) -> list[str]:
        return self.driver.status_lines() if self.driver is not None else []

    def custom_command(self, args: list[str]) -> int:
        d = self.driver
        if d is None:
            raise ModuleError(f"{self.name}: not started")
        verb, rest = args[0], args[1:]
        link = d.link
        if verb in ("safety_off", "safety_on"):
            reg = Setup.FORCE_SAFETY_OFF if verb == "safety_off" else Setup.FORCE_SAFETY_ON
            d.request(verb, lambda: link.write(PageNo.SETUP, reg, [FORCE_SAFETY_MAGIC]))
        elif verb == "limit":
            rate = self._int_arg(verb, rest, 1, 10_000)
            d.set_update_rate(rate)
            self.print(f"{self.name}: update limit {rate} Hz "
                       f"({d.sub_controls[0].interval_us // 1000} ms)")
            return 0
        elif verb == "mixer":
            if len(rest) != 1:
                raise UsageError("mixer needs one file name")
            name = rest[0]
            d.request(f"mixer {name}", lambda: d._upload_mixer(name))
        elif verb == "recovery":
            d.inair_restart_ok = True
            d.request(verb, d._send_arming)
        elif verb == "debug":
            level = self._int_arg(verb, rest, 0, 0xFFFF)
            d.request(verb, lambda: link.write(PageNo.SETUP, Setup.SET_DEBUG, [level]))
        else:
            return super().custom_command(args)
        self.print(f"{self.name}: {' '.join(args)} requested")
        return 0

    @staticmethod
    def _int_arg(verb: str, rest: list[str], lo: int, hi: int) -> int:
        if len(rest) != 1 or not rest[0].isdigit() or not lo <= int(rest[0]) <= hi:
            raise UsageError(f"{verb} needs one integer in {lo}..{hi}")
        return int(rest[0])
