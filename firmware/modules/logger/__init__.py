"""The logger module: ULog files of uORB topics, console messages and parameters."""

from firmware.modules.logger.logger import DEFAULT_UTC_EPOCH_S, Logger, SdWriteBuffer, log_path_for
from firmware.modules.logger.module import LoggerModule
from firmware.modules.logger.profiles import PROFILES, LoggedTopic, get_profile
from firmware.modules.logger.ulog import UlogError, UlogWriter

__all__ = [
           "DEFAULT_UTC_EPOCH_S",
           "PROFILES",
           "LoggedTopic",
           "Logger",
           "LoggerModule",
           "SdWriteBuffer",
           "UlogError",
           "UlogWriter",
           "get_profile",
           "log_path_for",
]
