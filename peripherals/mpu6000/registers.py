"""MPU-6000 register map as data, in the register map's names and order.

Sources: shared/reference/sensors.md section 1.4/1.5 (RM-MPU-6000A-00 rev 4.2 plus the
undocumented registers named by ArduPilot) and fixtures/mpu6000/mpu6000_register_reference.json.
Every register resets to 0x00 except PWR_MGMT_1 (0x40, asleep), WHO_AM_I (0x68), the
undocumented PRODUCT_ID (per part) and the factory self-test trims (per part, never 0).

Addresses that the map does not list (0x11, 0x12, 0x1D, 0x1E, 0x20-0x22, 0x39, 0x61, 0x62,
0x76-0x7F) are left out of the table on purpose: :class:`~peripherals.regs.RegisterFile` reads
them as 0x00 and ignores writes, which is what legacy PX4 relies on for 0x11.

The table is built by a function because two reset values belong to the part, not the type.
"""

from __future__ import annotations

import math
from typing import Final

from peripherals.regs import Field, Reg

__all__ = [
    "ACCEL_LSB_PER_G", "DATA_FIRST", "DATA_LAST", "DLPF_TABLE", "FAST_READ", "FIFO_SIZE",
    "GYRO_LSB_PER_DPS", "PRODUCT_IDS", "REV_C_IDS", "SELF_TEST_TRIM", "WHO_AM_I_VALUE",
    "mpu6000_registers", "self_test_response",
]

WHO_AM_I_VALUE: Final = 0x68
FIFO_SIZE: Final = 1024

# Register addresses and field masks, named ``REG`` and ``REG_FIELD`` after the table below
# (tests/peripherals/test_register_names.py checks every such name against it). The behaviour
# in ``model`` and ``sampling`` uses these, never a raw address or bit.
PRODUCT_ID: Final = 0x0C
SMPLRT_DIV: Final = 0x19
CONFIG: Final = 0x1A
CONFIG_DLPF_CFG: Final = 0x07
GYRO_CONFIG: Final = 0x1B
GYRO_CONFIG_XG_ST: Final = 0x80
GYRO_CONFIG_FS_SEL: Final = 0x18
GYRO_CONFIG_FS_SEL_LSB: Final = 3
ACCEL_CONFIG: Final = 0x1C
ACCEL_CONFIG_XA_ST: Final = 0x80
ACCEL_CONFIG_AFS_SEL: Final = 0x18
ACCEL_CONFIG_AFS_SEL_LSB: Final = 3
#: XG_ST | YG_ST | ZG_ST (and XA_ST | YA_ST | ZA_ST): the self-test bits, X first from bit 7.
SELF_TEST_BITS: Final = 0xE0
FIFO_EN: Final = 0x23
FIFO_EN_TEMP_FIFO_EN: Final = 0x80
FIFO_EN_XG_FIFO_EN: Final = 0x40
FIFO_EN_YG_FIFO_EN: Final = 0x20
FIFO_EN_ZG_FIFO_EN: Final = 0x10
FIFO_EN_ACCEL_FIFO_EN: Final = 0x08
INT_PIN_CFG: Final = 0x37
INT_PIN_CFG_INT_LEVEL: Final = 0x80
INT_PIN_CFG_INT_OPEN: Final = 0x40
INT_PIN_CFG_LATCH_INT_EN: Final = 0x20
INT_PIN_CFG_INT_RD_CLEAR: Final = 0x10
INT_ENABLE: Final = 0x38
INT_ENABLE_FIFO_OFLOW_EN: Final = 0x10
INT_ENABLE_DATA_RDY_EN: Final = 0x01
INT_STATUS: Final = 0x3A
INT_STATUS_FIFO_OFLOW_INT: Final = 0x10
INT_STATUS_DATA_RDY_INT: Final = 0x01
SIGNAL_PATH_RESET: Final = 0x68
SIGNAL_PATH_RESET_GYRO_RESET: Final = 0x04
SIGNAL_PATH_RESET_ACCEL_RESET: Final = 0x02
USER_CTRL: Final = 0x6A
USER_CTRL_FIFO_EN: Final = 0x40
USER_CTRL_FIFO_RESET: Final = 0x04
USER_CTRL_SIG_COND_RESET: Final = 0x01
#: DMP_RESET | FIFO_RESET | I2C_MST_RESET | SIG_COND_RESET: strobes that clear themselves.
USER_CTRL_STROBES: Final = 0x0F
PWR_MGMT_1: Final = 0x6B
PWR_MGMT_1_DEVICE_RESET: Final = 0x80
PWR_MGMT_1_SLEEP: Final = 0x40
PWR_MGMT_1_TEMP_DIS: Final = 0x08
PWR_MGMT_1_CLKSEL: Final = 0x07
#: CLKSEL 7: "stops the clock and keeps the timing generator in reset".
CLKSEL_STOP: Final = 7
PWR_MGMT_2: Final = 0x6C
FIFO_COUNTH: Final = 0x72
FIFO_COUNTL: Final = 0x73
FIFO_R_W: Final = 0x74
WHO_AM_I: Final = 0x75
#: ACCEL_XOUT_H .. GYRO_ZOUT_L: the block latched per sample and served consistently.
DATA_FIRST: Final = 0x3B
DATA_LAST: Final = 0x48
#: Registers readable at up to 20 MHz: INT_STATUS and the sensor data (datasheet), plus the
#: FIFO count and data port, which PX4 reads on its fast clock and which real parts serve.
FAST_READ: Final = frozenset(range(0x3A, 0x49)) | {0x72, 0x73, 0x74}

#: Known PRODUCT_ID codes: engineering samples 0x14-0x18, production 0x54-0x5A (legacy PX4).
PRODUCT_IDS: Final = {
    0x14: "MPU6000ES_REV_C4", 0x15: "MPU6000ES_REV_C5", 0x16: "MPU6000ES_REV_D6",
    0x17: "MPU6000ES_REV_D7", 0x18: "MPU6000ES_REV_D8", 0x54: "MPU6000_REV_C4",
    0x55: "MPU6000_REV_C5", 0x56: "MPU6000_REV_D6", 0x57: "MPU6000_REV_D7",
    0x58: "MPU6000_REV_D8", 0x59: "MPU6000_REV_D9", 0x5A: "MPU6000_REV_D10",
}
#: Rev C silicon doubles the accelerometer sensitivity (AFS_SEL=1 gives 4096 LSB/g).
REV_C_IDS: Final = frozenset({0x14, 0x15, 0x54, 0x55})

#: Factory self-test trims (SELF_TEST_X, _Y, _Z, _A). Chosen mid-range so the legacy PX4
#: factory test passes: accel trims 18/17/19, gyro trims 19/20/18 (5-bit codes).
SELF_TEST_TRIM = (0x93, 0x94, 0x92, 0x27)


def self_test_response(trims: tuple[int, int, int, int]) -> tuple[tuple[float, ...],
                                                                   tuple[float, ...]]:
    """Self-test output shift (accel in g, gyro in deg/s) implied by the trim codes.

    The datasheet formulas in counts (accel at 4096 LSB/g, gyro at 131 LSB/(deg/s)), turned
    into physical units so the shift is right at any full-scale setting. Y gyro is negated.
    """
    st_x, st_y, st_z, st_a = trims
    a_codes = (((st_x >> 3) & 0x1C) | ((st_a >> 4) & 3),
               ((st_y >> 3) & 0x1C) | ((st_a >> 2) & 3),
               ((st_z >> 3) & 0x1C) | (st_a & 3))
    g_codes = (st_x & 0x1F, st_y & 0x1F, st_z & 0x1F)
    accel_g = tuple(0.0 if a == 0 else 0.34 * (0.92 / 0.34) ** ((a - 1) / 30) for a in a_codes)
    gyro = [0.0 if g == 0 else 25.0 * 1.046 ** (g - 1) for g in g_codes]
    gyro[1] = -gyro[1]
    return accel_g, tuple(gyro)


def _rw(addr: int, name: str, doc: str = "", **kw) -> Reg:
    return Reg(addr, name, doc=doc, **kw)


def _ro(addr: int, name: str, doc: str = "", reset: int = 0) -> Reg:
    return Reg(addr, name, reset=reset, access="r", doc=doc)


def mpu6000_registers(product_id: int, trims: tuple[int, int, int, int]) -> list[Reg]:
    """The register table of one part (its PRODUCT_ID and self-test trims)."""
    regs: list[Reg] = []
    for i, axis in enumerate("XYZ"):
        regs.append(_rw(0x00 + i, f"{axis}G_OFFS_TC", "undocumented gyro offset/TC trim"))
    for i, axis in enumerate("XYZ"):
        regs.append(_rw(0x03 + i, f"{axis}_FINE_GAIN", "undocumented"))
    for i, axis in enumerate("XYZ"):
        regs.append(_rw(0x06 + 2 * i, f"{axis}A_OFFS_H", "undocumented accel offset trim"))
        regs.append(_rw(0x07 + 2 * i, f"{axis}A_OFFS_L", "undocumented accel offset trim"))
    regs.append(_ro(0x0C, "PRODUCT_ID", "undocumented: product and silicon revision",
                    reset=product_id))
    st = [Field("A_TEST", 5, 3, "accel trim bits 4:2"), Field("G_TEST", 0, 5, "gyro trim")]
    for i, axis in enumerate("XYZ"):
        regs.append(Reg(0x0D + i, f"SELF_TEST_{axis}", reset=trims[i], fields=list(st)))
    regs.append(Reg(0x10, "SELF_TEST_A", reset=trims[3],
                    fields=[Field("XA_TEST", 4, 2), Field("YA_TEST", 2, 2),
                            Field("ZA_TEST", 0, 2)]))
    for i, axis in enumerate("XYZ"):
        regs.append(_rw(0x13 + 2 * i, f"{axis}G_OFFS_USRH", "undocumented user gyro offset"))
        regs.append(_rw(0x14 + 2 * i, f"{axis}G_OFFS_USRL", "undocumented user gyro offset"))
    regs += [
        _rw(0x19, "SMPLRT_DIV", "sample rate = gyro output rate / (1 + SMPLRT_DIV)"),
        Reg(0x1A, "CONFIG", fields=[Field("EXT_SYNC_SET", 3, 3), Field("DLPF_CFG", 0, 3)]),
        Reg(0x1B, "GYRO_CONFIG", fields=[Field("XG_ST", 7), Field("YG_ST", 6),
                                         Field("ZG_ST", 5), Field("FS_SEL", 3, 2)]),
        Reg(0x1C, "ACCEL_CONFIG", fields=[Field("XA_ST", 7), Field("YA_ST", 6),
                                          Field("ZA_ST", 5), Field("AFS_SEL", 3, 2)]),
        _rw(0x1F, "MOT_THR", "motion threshold, 2 mg/LSB (motion detection not modelled)"),
        Reg(0x23, "FIFO_EN", fields=[Field("TEMP_FIFO_EN", 7), Field("XG_FIFO_EN", 6),
                                     Field("YG_FIFO_EN", 5), Field("ZG_FIFO_EN", 4),
                                     Field("ACCEL_FIFO_EN", 3), Field("SLV2_FIFO_EN", 2),
                                     Field("SLV1_FIFO_EN", 1), Field("SLV0_FIFO_EN", 0)]),
        _rw(0x24, "I2C_MST_CTRL", "aux I2C master (unused on FMUv2, not modelled)"),
    ]
    for slv in range(4):
        base = 0x25 + 3 * slv
        regs += [_rw(base, f"I2C_SLV{slv}_ADDR"), _rw(base + 1, f"I2C_SLV{slv}_REG"),
                 _rw(base + 2, f"I2C_SLV{slv}_CTRL")]
    regs += [
        _rw(0x31, "I2C_SLV4_ADDR"), _rw(0x32, "I2C_SLV4_REG"), _rw(0x33, "I2C_SLV4_DO"),
        _rw(0x34, "I2C_SLV4_CTRL"), _ro(0x35, "I2C_SLV4_DI"), _ro(0x36, "I2C_MST_STATUS"),
        Reg(0x37, "INT_PIN_CFG", fields=[
            Field("INT_LEVEL", 7, doc="1: active low"), Field("INT_OPEN", 6),
            Field("LATCH_INT_EN", 5, doc="0: 50 us pulse, 1: held until cleared"),
            Field("INT_RD_CLEAR", 4, doc="1: any read clears INT_STATUS"),
            Field("FSYNC_INT_LEVEL", 3), Field("FSYNC_INT_EN", 2), Field("I2C_BYPASS_EN", 1)]),
        Reg(0x38, "INT_ENABLE", fields=[Field("MOT_EN", 6), Field("FIFO_OFLOW_EN", 4),
                                        Field("I2C_MST_INT_EN", 3), Field("DATA_RDY_EN", 0)]),
        Reg(0x3A, "INT_STATUS", access="r", doc="read clears; bits as INT_ENABLE", fields=[
            Field("MOT_INT", 6), Field("FIFO_OFLOW_INT", 4), Field("I2C_MST_INT", 3),
            Field("DATA_RDY_INT", 0)]),
    ]
    for i, name in enumerate(("ACCEL_XOUT", "ACCEL_YOUT", "ACCEL_ZOUT", "TEMP_OUT",
                              "GYRO_XOUT", "GYRO_YOUT", "GYRO_ZOUT")):
        addr = DATA_FIRST + 2 * i
        regs += [_ro(addr, f"{name}_H", "sample data, BE int16"), _ro(addr + 1, f"{name}_L")]
    regs += [_ro(0x49 + i, f"EXT_SENS_DATA_{i:02d}", "aux I2C data (not modelled)")
             for i in range(24)]
    regs += [_rw(0x63 + i, f"I2C_SLV{i}_DO") for i in range(4)]
    regs += [
        _rw(0x67, "I2C_MST_DELAY_CTRL"),
        Reg(0x68, "SIGNAL_PATH_RESET", access="w", fields=[
            Field("GYRO_RESET", 2), Field("ACCEL_RESET", 1), Field("TEMP_RESET", 0)],
            doc="strobes: reset the filters, keep the data registers; read as 0"),
        _rw(0x69, "MOT_DETECT_CTRL"),
        Reg(0x6A, "USER_CTRL", fields=[
            Field("DMP_EN", 7), Field("FIFO_EN", 6), Field("I2C_MST_EN", 5),
            Field("I2C_IF_DIS", 4), Field("DMP_RESET", 3), Field("FIFO_RESET", 2),
            Field("I2C_MST_RESET", 1), Field("SIG_COND_RESET", 0)]),
        Reg(0x6B, "PWR_MGMT_1", reset=0x40, fields=[
            Field("DEVICE_RESET", 7), Field("SLEEP", 6), Field("CYCLE", 5),
            Field("TEMP_DIS", 3), Field("CLKSEL", 0, 3)]),
        Reg(0x6C, "PWR_MGMT_2", fields=[
            Field("LP_WAKE_CTRL", 6, 2), Field("STBY_XA", 5), Field("STBY_YA", 4),
            Field("STBY_ZA", 3), Field("STBY_XG", 2), Field("STBY_YG", 1), Field("STBY_ZG", 0)]),
        _rw(0x6D, "BANK_SEL", "undocumented DMP access (not modelled)"),
        _rw(0x6E, "MEM_START_ADDR"), _rw(0x6F, "MEM_R_W"),
        _rw(0x70, "DMP_CFG_1"), _rw(0x71, "DMP_CFG_2"),
        _ro(0x72, "FIFO_COUNTH", "bytes in FIFO; reading H latches L"),
        _ro(0x73, "FIFO_COUNTL"),
        _rw(0x74, "FIFO_R_W", "FIFO data port: no auto-increment"),
        _ro(0x75, "WHO_AM_I", reset=WHO_AM_I_VALUE),
    ]
    return regs


#: DLPF_CFG -> (accel bandwidth Hz, gyro bandwidth Hz, gyro output rate Hz). Code 7 is
#: reserved: modelled as 8 kHz with no filtering beyond the sensor's own (3.6 kHz gyro).
DLPF_TABLE: Final = {
    0: (260.0, 256.0, 8000), 1: (184.0, 188.0, 1000), 2: (94.0, 98.0, 1000),
    3: (44.0, 42.0, 1000), 4: (21.0, 20.0, 1000), 5: (10.0, 10.0, 1000),
    6: (5.0, 5.0, 1000), 7: (260.0, 3600.0, 8000),
}

#: LSB per unit for each FS_SEL (per deg/s) and AFS_SEL (per g), datasheet nominal.
GYRO_LSB_PER_DPS: Final[tuple[float, ...]] = (131.0, 65.5, 32.8, 16.4)
ACCEL_LSB_PER_G: Final[tuple[float, ...]] = (16384.0, 8192.0, 4096.0, 2048.0)
DEG: Final = math.pi / 180.0
