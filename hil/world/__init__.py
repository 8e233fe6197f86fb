"""The world outside the boards: JSBSim vehicle, ESCs, battery, atmosphere, Earth field.

Entry point: :class:`World`. Everything is SI; frames are PX4's (body FRD, NED).
"""

from .battery import Battery, BatteryParams
from .esc import Esc, EscParams
from common.truth import Truth
from .world import PX4_HOME, World

__all__ = ["World", "Truth", "Esc", "EscParams", "Battery", "BatteryParams", "PX4_HOME"]
