"""Attitude controller selection by parameter (``mc_att_select``, ``MC_ATT_IMPL``)."""

from firmware.modules.mc_att_select.mc_att_select import IMPLS, PARAMS, McAttSelectModule

__all__ = ["IMPLS", "PARAMS", "McAttSelectModule"]
