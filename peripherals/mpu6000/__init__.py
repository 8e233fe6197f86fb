"""InvenSense MPU-6000 6-axis IMU model (SPI1 on FMUv2, CS PC2, INT on PD15).

``model`` holds the chip (SPI target, INT pin, faults), ``registers`` the register map as
data, ``sampling`` the signal chain, ``rotation`` the mounting rotation.
"""

from peripherals.mpu6000.model import Mpu6000, default_accel_errors, default_gyro_errors
from peripherals.mpu6000.registers import PRODUCT_IDS, WHO_AM_I_VALUE
from peripherals.mpu6000.rotation import PX4_ROTATIONS, board_to_sensor

__all__ = [
           "PRODUCT_IDS",
           "PX4_ROTATIONS",
           "WHO_AM_I_VALUE",
           "Mpu6000",
           "board_to_sensor",
           "default_accel_errors",
           "default_gyro_errors",
]
