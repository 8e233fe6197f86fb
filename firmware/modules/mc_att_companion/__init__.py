"""Multicopter attitude law on the companion computer, the FMU's law as fallback
(``mc_att_companion``, ``MC_ATT_IMPL`` 2)."""

from firmware.modules.mc_att_companion.mc_att_companion import PARAMS, McAttCompanionModule

__all__ = ["PARAMS", "McAttCompanionModule"]
