"""Two systems joined by a serial cable in one kernel: the uORB bridge's test rig.

Each side is a :class:`firmware.system.System` with its own platform (uORB broker, work
queues, HRT) and one USART behind a device name, as a board gives it; the USARTs are joined
by a full-duplex :class:`board.uart.UartWire`. Both platforms share one kernel, so there is one
virtual time and latencies are exact. Cheap: no board boots, nothing but the bridge runs.
"""

from __future__ import annotations

from pathlib import Path

from board.kernel import Kernel
from board.uart import Uart, UartConfig, UartWire
from firmware.modules.uorb_bridge import UorbBridgeModule
from firmware.platform import Platform
from firmware.system import System

ROMFS_TOPICS = Path(__file__).resolve().parents[2] / "firmware" / "romfs" / "bridge" / "topics.yaml"


class _Hw:
    """What the bridge needs from a board: its UART by device name."""

    adc = None

    def __init__(self, uarts: dict[str, Uart]) -> None:
        self._uarts = uarts

    def uart_by_device(self, device: str) -> Uart | None:
        return self._uarts.get(device)


class Side:
    def __init__(self, kernel: Kernel, name: str, device: str, sd_root: Path | None) -> None:
        self.platform = Platform(kernel)
        self.uart = Uart(kernel, f"{name}:telem", UartConfig(baud=921600))
        self.device = device
        self.lines: list[str] = []
        self.system = System(self.platform, None, modules={"uorb_bridge": UorbBridgeModule},
                             hw=_Hw({device: self.uart}), sd_root=sd_root,
                             console=self.lines.append)
        self.orb = self.platform.orb

    def cmd(self, line: str) -> int:
        """Run ``uorb_bridge ...`` as the shell would; output in ``lines``."""
        words = line.split()
        assert words[0] == "uorb_bridge"
        return self.system.modules.command("uorb_bridge", words[1:])

    @property
    def bridge(self) -> UorbBridgeModule:
        inst = self.system.modules.get("uorb_bridge")
        assert isinstance(inst, UorbBridgeModule)
        return inst

    def publish(self, topic: str, msg: object, instance: int = 0) -> None:
        self.orb.advertise(topic, instance).publish(msg)

    def dmesg(self) -> list[str]:
        return [text for _t, _sev, _mod, text in self.platform.dmesg]


class Rig:
    """An FMU side and a companion side on one kernel, wired (not started)."""

    def __init__(self, sd_root: Path | None = None) -> None:
        self.kernel = Kernel("bridge-rig")
        self.fmu = Side(self.kernel, "fmu", "/dev/ttyS2", sd_root)
        self.comp = Side(self.kernel, "companion", "/dev/ttyUSB0", sd_root)
        self.wire = UartWire(self.fmu.uart, self.comp.uart)

    def start(self, config: str = "/etc/bridge/topics.yaml") -> None:
        assert self.fmu.cmd(f"uorb_bridge start -d /dev/ttyS2 -r fmu -c {config}") == 0, \
            self.fmu.lines
        assert self.comp.cmd(f"uorb_bridge start -d /dev/ttyUSB0 -r companion -c {config}") \
            == 0, self.comp.lines

    def run_ms(self, ms: float) -> None:
        self.kernel.run(self.kernel.now_ns + int(ms * 1e6))

    @property
    def now_us(self) -> int:
        return self.kernel.now_ns // 1000
