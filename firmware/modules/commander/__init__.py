"""commander: arming state machine, preflight checks, flight modes and failsafes."""

from firmware.modules.commander.commander import CommanderModule
from firmware.modules.commander.params import PARAMS

__all__ = ["PARAMS", "CommanderModule"]
