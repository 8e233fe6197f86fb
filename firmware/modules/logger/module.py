"""``logger start|stop|status``: the logger as a shell module.

Files go to the emulated SD card's ``log`` folder. ``SDLOG_MODE`` chooses when (0: from arming
to disarming, 1 and 2: from boot); ``SDLOG_PROFILE`` bit 4 adds the high-rate set, bit 6 the raw
sensors. File names use GPS UTC time once the GPS has it, else a fixed epoch plus virtual
time, so runs stay deterministic.
"""

from __future__ import annotations

from typing import Any

from firmware.modules.logger.logger import Logger, version_info
from firmware.platform.module import ModuleBase, ModuleError
from firmware.platform.uorb import Subscription

__all__ = ["LoggerModule"]


class LoggerModule(ModuleBase):
    NAME = "logger"
    DESCRIPTION = "ULog logger: uORB topics, console messages and parameters to the SD card"

    def __init__(self, system: Any, args: Any = ()) -> None:
        super().__init__(system, args)
        self.logger: Logger | None = None
        self._gps: Subscription | None = None
        self._utc_offset_us: int | None = None

    def _utc_us(self) -> int:
        # The first GPS time seen anchors UTC to virtual time (as PX4 sets its clock from GPS).
        if self._utc_offset_us is None and self._gps is not None:
            fix = self._gps.copy()
            if fix is not None and fix.time_utc_usec:
                self._utc_offset_us = fix.time_utc_usec - fix.timestamp
        if self._utc_offset_us is None:
            assert self.logger is not None  # UTC is asked of a running logger
            return self.logger.utc_epoch_s * 1_000_000 + self.platform.hrt.absolute_time()
        return self._utc_offset_us + self.platform.hrt.absolute_time()

    def _start(self) -> None:
        if self.system.sd_root is None:
            raise ModuleError("no SD card (the board has no sd_root): nothing to log to")
        params = self.system.params
        mode_param = int(params["SDLOG_MODE"]) if params is not None else 0
        if mode_param < 0:
            raise ModuleError("SDLOG_MODE is -1: logging disabled")
        profile_bits = int(params["SDLOG_PROFILE"]) if params is not None else 1
        profile = "default"
        if profile_bits & (1 << 4):
            profile += "+high_rate"
        if profile_bits & (1 << 6):
            profile += "+sensors"
        log_root = self.system.resolve_path("/fs/microsd/log")
        log_root.mkdir(parents=True, exist_ok=True)
        if "sensor_gps" in self.platform.orb.registry.topics:
            self._gps = Subscription(self.platform.orb, "sensor_gps")
        system = self.system
        info = version_info(system.version, system.hw_arch, system.git_hash, system.board_name)
        self.logger = Logger(
            self.platform, log_root, profile, "arm" if mode_param == 0 else "boot",
            params_provider=(lambda: dict(params.values)) if params is not None else None,
            utc_us=self._utc_us, info=info)
        self.add_work_item(self.logger)
        self.logger.start()

    def _stop(self) -> None:
        if self.logger is not None:
            self.logger.stop()

    def status_lines(self) -> list[str]:
        return self.logger.status().splitlines() if self.logger is not None else []
