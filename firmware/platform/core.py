"""The :class:`Platform` of a board (see the package docstring): the kernel's services as PX4's
modules see them (HRT, uORB, work queues, perf counters, the log)."""

from __future__ import annotations

from typing import Any, Final

from board.kernel import Kernel
from firmware.platform.hrt import Hrt
from firmware.platform.msgdef import MessageRegistry
from firmware.platform.perf import PerfRegistry
from firmware.platform.uorb import Broker, Publication
from firmware.platform.workqueue import WorkQueueManager

__all__ = ["Platform", "SEV_EMERG", "SEV_ERR", "SEV_WARN", "SEV_INFO", "SEV_DEBUG"]


#: syslog severities used by PX4's log_message
SEV_EMERG: Final = 0
SEV_ERR: Final = 3
SEV_WARN: Final = 4
SEV_INFO: Final = 6
SEV_DEBUG: Final = 7
_LEVEL_NAMES: Final = {SEV_EMERG: "EMERG", SEV_ERR: "ERROR", SEV_WARN: "WARN", SEV_INFO: "INFO", SEV_DEBUG: "DEBUG"}

DMESG_LINES: Final = 2000


class Platform:
    def __init__(self, kernel: Kernel, registry: MessageRegistry | None = None) -> None:
        self.kernel = kernel
        self.hrt = Hrt(kernel)
        self.orb = Broker(self.hrt, registry)
        self.wq = WorkQueueManager(kernel)
        self.perf = PerfRegistry(self.hrt)
        #: (t_us, severity, module, text) of every message since boot (the shell's dmesg)
        self.dmesg: list[tuple[int, int, str, str]] = []
        self._log_pub: Publication | None = None
        self._log_msg: Any = None

    def time_us(self) -> int:
        """``hrt_absolute_time()``, read from the kernel inline (the hottest call of modules)."""
        k = self.kernel
        return (k.now_ns + k.busy_ns) // 1000

    # -- PX4_INFO / PX4_WARN / PX4_ERR ---------------------------------------------------------

    def log(self, severity: int, module: str, text: str) -> None:
        """Record a message in dmesg and publish it on ``log_message`` (for logger and GCS)."""
        t = self.hrt.absolute_time()
        self.dmesg.append((t, severity, module, text))
        if len(self.dmesg) > DMESG_LINES:
            del self.dmesg[: len(self.dmesg) - DMESG_LINES]
        if severity > SEV_INFO:
            return
        pub = self._log_pub
        if pub is None:
            pub = self._log_pub = self.orb.advertise("log_message")
            self._log_msg = self.orb.new("log_message")
        msg = self._log_msg
        msg.timestamp = t
        msg.severity = severity
        msg.text = f"[{module}] {text}"[:126]
        pub.publish(msg)

    def info(self, module: str, text: str) -> None:
        self.log(SEV_INFO, module, text)

    def warn(self, module: str, text: str) -> None:
        self.log(SEV_WARN, module, text)

    def error(self, module: str, text: str) -> None:
        self.log(SEV_ERR, module, text)

    def emergency(self, module: str, text: str) -> None:
        self.log(SEV_EMERG, module, text)

    def dmesg_text(self) -> str:
        return "\n".join(f"[{t / 1e6:10.6f}] {_LEVEL_NAMES.get(sev, sev)} [{mod}] {text}"
                         for t, sev, mod, text in self.dmesg)
