"""Airspeed (differential pressure) sensor drivers."""

from firmware.drivers.airspeed.ms4525 import Ms4525Driver

__all__ = ["Ms4525Driver"]
