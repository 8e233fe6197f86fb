"""Multicopter land detector (``land_detector``)."""

from firmware.modules.land_detector.land_detector import PARAMS, LandDetectorModule

__all__ = ["PARAMS", "LandDetectorModule"]
