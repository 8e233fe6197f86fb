"""load_mon: the processor load on ``cpuload`` (PX4's resource load monitor)."""

from firmware.modules.load_mon.load_mon import LoadMonModule

__all__ = ["LoadMonModule"]
