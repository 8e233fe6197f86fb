"""The ekf2 module: the attitude and navigation estimator."""

from firmware.modules.ekf2.core import Ekf, NoiseParams
from firmware.modules.ekf2.module import Ekf2Module
from firmware.modules.ekf2.params import PARAMS

__all__ = ["PARAMS", "Ekf", "Ekf2Module", "NoiseParams"]
