"""E14 register pages through the wire: FMU-side encode -> IO handler -> FMU-side decode."""

from __future__ import annotations

import math

import pytest

from ioproc.mixer import encode_mixer_upload
from ioproc.pages import PAGE_TABLES, IoHooks, IoPages, _float_to_u16
from ioproc.protocol import (
    ERA,
    Alarms,
    Arming,
    Features,
    PageNo,
    ReplyCode,
    Setup,
    Status,
    StatusFlags,
    decode_reply,
    encode_read,
    encode_write,
    handle_request,
)


class Io:
    """An IO register file plus the calls the FMU driver would make."""

    def __init__(self, **hooks) -> None:
        self.calls: list[tuple] = []
        self.regs = IoPages(hooks=IoHooks(**hooks), firmware_crc=0x2DFD2D88)

    def read(self, page: int, offset: int, count: int):
        return decode_reply(handle_request(encode_read(page, offset, count), self.regs, 0))

    def write(self, page: int, offset: int, values, now_us: int = 0) -> ReplyCode:
        reply = decode_reply(handle_request(encode_write(page, offset, values), self.regs,
                                            now_us))
        assert reply.values == () and (reply.page, reply.offset) == (page, offset)
        return reply.code

    def values(self, page: int, offset: int = 0, count: int = 32) -> tuple[int, ...]:
        reply = self.read(page, offset, count)
        assert reply.ok
        return reply.values


OK, ERR = ReplyCode.SUCCESS, ReplyCode.ERROR


@pytest.fixture
def io() -> Io:
    return Io()


def test_page_lengths_match_reference() -> None:
    lengths = {p.number: p.length for p in PAGE_TABLES[ERA].values() if p.readable}
    assert lengths == {0: 9, 1: 9, 2: 8, 3: 8, 4: 25, 5: 10, 6: 32, 7: 32, 50: 14, 51: 32,
                       53: 108, 54: 8, 55: 8, 106: 8, 107: 8, 108: 8}


def test_every_hook_named_in_the_tables_exists() -> None:
    for spec in PAGE_TABLES[ERA].values():
        if spec.bulk_write:
            assert callable(getattr(IoPages, "_bulk_" + spec.bulk_write))
        for hook in [*spec.writes.values(), spec.default_write]:
            if hook not in (None, "ignore"):
                assert callable(getattr(IoPages, "_w_" + hook))


def test_register_access_table() -> None:
    pages = PAGE_TABLES[ERA]
    assert pages[PageNo.CONFIG].access(0) == "r"
    assert pages[PageNo.SETUP].access(Setup.ARMING) == "rw"
    assert pages[PageNo.SETUP].access(Setup.CRC) == "r"
    assert pages[PageNo.SETUP].access(Setup.FORCE_SAFETY_ON) == "w"
    assert pages[PageNo.SETUP].access(Setup.RESERVED_8) == "r"
    assert pages[PageNo.STATUS].access(Status.FREEMEM) == "r+ignored"
    assert pages[PageNo.MIXERLOAD].access(0) == "w"
    assert pages[PageNo.TEST].access(3) == "ignored"


def test_config_read_only(io: Io) -> None:
    assert io.values(PageNo.CONFIG) == (4, 2, 3, 64, 8, 8, 18, 2, 0)
    assert io.write(PageNo.CONFIG, 0, [5]) is ERR
    assert io.values(PageNo.CONFIG, 0, 1) == (4,)
    assert io.write(PageNo.CONFIG, 0, []) is OK  # zero-length: no register to refuse (quirk)


@pytest.mark.parametrize("page", [PageNo.ACTUATORS, PageNo.SERVOS, PageNo.RAW_RC_INPUT,
                                  PageNo.RC_INPUT, PageNo.RAW_ADC_INPUT, PageNo.PWM_INFO,
                                  PageNo.SENSORS, 99])
def test_read_only_and_unknown_pages_refuse_writes(io: Io, page: int) -> None:
    assert io.write(page, 0, [1234]) is ERR


def test_status_refresh_and_writes() -> None:
    io = Io(adc_measure=lambda ch: {4: 2069, 5: 1241}[ch], freemem=lambda: 1500)
    status = io.values(PageNo.STATUS)
    assert len(status) == 9 and status[Status.FREEMEM] == 1500
    assert status[Status.VSERVO] == 2069 * 9900 // 4096 and status[Status.VRSSI] == 999
    assert io.values(PageNo.RAW_ADC_INPUT)[:3] == (2069, 1241, 0)
    io.regs.alarms = Alarms.FMU_LOST | Alarms.RC_LOST
    assert io.write(PageNo.STATUS, Status.ALARMS, [Alarms.RC_LOST]) is OK
    assert io.regs.alarms == Alarms.FMU_LOST
    assert io.write(PageNo.STATUS, Status.FLAGS,
                    [StatusFlags.SAFETY_OFF | StatusFlags.ARM_SYNC]) is OK
    assert io.regs.status_flags == StatusFlags.SAFETY_OFF | StatusFlags.ARM_SYNC
    assert io.write(PageNo.STATUS, Status.FLAGS, [0]) is OK  # ignored once ARM_SYNC is set
    assert io.regs.status_flags == StatusFlags.SAFETY_OFF | StatusFlags.ARM_SYNC
    assert io.write(PageNo.STATUS, Status.FREEMEM, [1, 2, 3, 4, 5, 6, 7, 8, 9, 10]) is OK


def test_pwm_info_groups(io: Io) -> None:
    assert io.values(PageNo.PWM_INFO)[:4] == (0x03, 0xF0, 0x0C, 0)


def test_setup_reset_values_and_crc(io: Io) -> None:
    setup = io.values(PageNo.SETUP)
    assert len(setup) == 14
    assert setup[Setup.FEATURES] == Features.ADC_RSSI
    assert setup[Setup.PWM_DEFAULTRATE] == 50 and setup[Setup.PWM_ALTRATE] == 200
    assert setup[Setup.VSERVO_SCALE] == 10000
    assert (setup[Setup.CRC], setup[Setup.CRC_HIGH]) == (0x2D88, 0x2DFD)


def test_setup_features_priority(io: Io) -> None:
    io.write(PageNo.SETUP, Setup.FEATURES, [0xFF])
    assert io.regs.page(PageNo.SETUP)[Setup.FEATURES] == Features.SBUS1_OUT
    io.write(PageNo.SETUP, Setup.FEATURES, [Features.PWM_RSSI | Features.ADC_RSSI])
    assert io.regs.page(PageNo.SETUP)[Setup.FEATURES] == Features.ADC_RSSI


def test_setup_arming_sticky_termination(io: Io) -> None:
    io.write(PageNo.SETUP, Setup.ARMING, [0xFFFF])
    assert io.regs.arming == 0x7FF
    assert io.regs.status_flags & StatusFlags.INIT_OK  # RC_HANDLING_DISABLED sets INIT_OK
    io.write(PageNo.SETUP, Setup.ARMING, [0])
    assert io.regs.arming == Arming.TERMINATION_FAILSAFE | Arming.FORCE_FAILSAFE


def test_setup_rates_algorithm() -> None:
    programmed: list[tuple[int, int]] = []
    io = Io(set_rate_group=lambda g, hz: programmed.append((g, hz)) or True)
    assert io.write(PageNo.SETUP, Setup.PWM_ALTRATE, [490]) is OK  # clamped to 400
    assert programmed == [(0, 50), (1, 50), (2, 50)]
    programmed.clear()
    io.write(PageNo.SETUP, Setup.PWM_RATES, [0x0F])  # groups 0 and 2 at the alternate rate
    assert programmed == [(0, 400), (1, 50), (2, 400)]
    io.write(PageNo.SETUP, Setup.PWM_RATES, [0x01])  # splits group 0: illegal
    assert io.regs.alarms & Alarms.PWM_ERROR
    assert io.regs.page(PageNo.SETUP)[Setup.PWM_RATES] == 0x0F
    programmed.clear()
    io.write(PageNo.SETUP, Setup.PWM_DEFAULTRATE, [10])
    assert io.regs.page(PageNo.SETUP)[Setup.PWM_DEFAULTRATE] == 50


def test_setup_unknown_register_and_partial_application(io: Io) -> None:
    for reg in (Setup.RELAYS_PAD, Setup.RESERVED_8, Setup.CRC, 15, 200):
        assert io.write(PageNo.SETUP, reg, [1]) is ERR
    # registers 6, 7 applied, 8 refused, 9 never reached
    assert io.write(PageNo.SETUP, Setup.VSERVO_SCALE, [9000, 0, 1, 3]) is ERR
    setup = io.regs.page(PageNo.SETUP)
    assert setup[Setup.VSERVO_SCALE] == 9000 and setup[Setup.SET_DEBUG] == 0


def test_setup_magic_registers() -> None:
    binds: list[tuple[int, int]] = []
    io = Io(dsm_bind=lambda cmd, pulses: binds.append((cmd, pulses)))
    assert io.write(PageNo.SETUP, Setup.FORCE_SAFETY_OFF, [1]) is OK  # E14 ignores bad values
    assert not io.regs.status_flags & StatusFlags.SAFETY_OFF
    io.write(PageNo.SETUP, Setup.FORCE_SAFETY_OFF, [22027])
    assert io.regs.status_flags & StatusFlags.SAFETY_OFF
    assert io.values(PageNo.SETUP, Setup.CRC_HIGH, 1) == (io.regs.page(PageNo.SETUP)[12],)
    io.write(PageNo.SETUP, Setup.REBOOT_BL, [14662], now_us=7)
    assert io.regs.reboot_at_us is None  # refused while safety is off
    assert io.write(PageNo.SETUP, Setup.FORCE_SAFETY_ON, [22027]) is OK
    assert not io.regs.status_flags & StatusFlags.SAFETY_OFF
    io.write(PageNo.SETUP, Setup.REBOOT_BL, [14661], now_us=7)
    assert io.regs.reboot_at_us is None
    io.write(PageNo.SETUP, Setup.REBOOT_BL, [14662], now_us=7)
    assert io.regs.reboot_at_us == 100_007
    io.write(PageNo.SETUP, Setup.RC_THR_FAILSAFE_US, [650])
    assert io.regs.page(PageNo.SETUP)[Setup.RC_THR_FAILSAFE_US] == 0
    io.write(PageNo.SETUP, Setup.RC_THR_FAILSAFE_US, [950])
    assert io.regs.page(PageNo.SETUP)[Setup.RC_THR_FAILSAFE_US] == 950
    io.write(PageNo.SETUP, Setup.DSM, [0x93])
    assert binds == [(3, 9)]


def test_controls_write(io: Io) -> None:
    io.regs.status_flags = StatusFlags.RAW_PWM
    assert io.write(PageNo.CONTROLS, 8, list(range(30)), now_us=1234) is OK
    controls = io.values(PageNo.CONTROLS)
    assert controls[:8] == (0,) * 8 and controls[8:] == tuple(range(24))  # past 32 dropped
    assert io.regs.fmu_data_received_us == 1234
    assert io.regs.status_flags == StatusFlags.FMU_OK


def test_direct_pwm_writes_servos(io: Io) -> None:
    io.write(PageNo.DIRECT_PWM, 0, [1500] * 8, now_us=9)
    io.write(PageNo.DIRECT_PWM, 6, [0xFFFF, 1100, 1200, 1300])
    assert io.values(PageNo.SERVOS) == (1500,) * 7 + (1100,)
    assert io.values(PageNo.DIRECT_PWM) == io.values(PageNo.SERVOS)
    assert io.regs.status_flags & (StatusFlags.RAW_PWM | StatusFlags.FMU_OK) == \
        StatusFlags.RAW_PWM | StatusFlags.FMU_OK


def test_pwm_value_pages_clamp(io: Io) -> None:
    io.write(PageNo.FAILSAFE_PWM, 0, [0, 800, 1500, 2500])
    assert io.values(PageNo.FAILSAFE_PWM)[:4] == (0, 900, 1500, 2100)
    assert io.regs.arming & Arming.FAILSAFE_CUSTOM
    io.write(PageNo.CONTROL_MIN_PWM, 0, [0, 500, 1075, 1400])
    assert io.values(PageNo.CONTROL_MIN_PWM)[:5] == (1000, 900, 1075, 1300, 1000)
    io.write(PageNo.CONTROL_MAX_PWM, 0, [1500, 1950, 2500])
    assert io.values(PageNo.CONTROL_MAX_PWM)[:4] == (1700, 1950, 2100, 2000)
    io.write(PageNo.DISARMED_PWM, 0, [900, 0, 3000])
    assert io.values(PageNo.DISARMED_PWM)[:3] == (900, 0, 2100)
    assert io.regs.arming & Arming.ALWAYS_PWM_ENABLE
    io.write(PageNo.DISARMED_PWM, 0, [0] * 8)
    assert not io.regs.arming & Arming.ALWAYS_PWM_ENABLE


def test_rc_config_rules(io: Io) -> None:
    assert io.write(PageNo.RC_CONFIG, 6, [1100, 1520, 1900, 10, 2, 3]) is OK  # channel 2
    assert io.values(PageNo.RC_CONFIG, 6, 6) == (1100, 1520, 1900, 10, 2, 3)
    assert io.regs.status_flags & StatusFlags.INIT_OK
    io.write(PageNo.RC_CONFIG, 6, [1000])  # any register write drops REVERSE
    assert io.values(PageNo.RC_CONFIG, 11, 1) == (1,)
    io.write(PageNo.RC_CONFIG, 12, [400, 1500, 2000, 30, 0, 1])  # MIN < 500
    assert io.values(PageNo.RC_CONFIG, 17, 1) == (0,)
    assert not io.regs.status_flags & StatusFlags.INIT_OK
    io.write(PageNo.RC_CONFIG, 18, [1000, 1500, 2000, 30, 255, 1])  # unassigned: disabled
    assert io.values(PageNo.RC_CONFIG, 23, 1) == (0,)
    assert io.write(PageNo.RC_CONFIG, 108, [1]) is ERR  # channel 19
    assert io.read(PageNo.RC_CONFIG, 108, 1).code is ERR
    io.regs.status_flags |= StatusFlags.SAFETY_OFF
    assert io.write(PageNo.RC_CONFIG, 0, [1234]) is OK
    assert io.values(PageNo.RC_CONFIG, 0, 1) == (1000,)


def test_per_register_write_truncated_at_255(io: Io) -> None:
    assert io.write(PageNo.STATUS, 250, [0] * 10) is OK
    assert io.write(PageNo.SETUP, 255, [1]) is OK  # nothing left to write after truncation


def test_test_page_led() -> None:
    leds: list[bool] = []
    io = Io(set_amber_led=leds.append)
    assert io.write(PageNo.TEST, 0, [3, 7]) is OK
    assert leds == [True]
    assert io.read(PageNo.TEST, 0, 1).code is ERR


QUAD_X = "R: 4x 10000 10000 10000 0\n"


def upload(io: Io, text: str) -> list[ReplyCode]:
    return [io.write(PageNo.MIXERLOAD, 0, chunk) for chunk in encode_mixer_upload(text)]


def test_mixer_upload_sets_mixer_ok_and_failsafe(io: Io) -> None:
    assert upload(io, QUAD_X) == [OK, OK]
    assert io.regs.status_flags & StatusFlags.MIXER_OK
    assert io.values(PageNo.FAILSAFE_PWM) == (900,) * 4 + (0,) * 4
    text = "".join(f"M: 1\nO: 10000 10000 0 -10000 10000\nS: 0 {i} 10000 10000 0 -10000 "
                   "10000\n" for i in range(4))
    assert len(text) > 59 * 2  # several chunks
    upload(io, text)
    assert io.regs.status_flags & StatusFlags.MIXER_OK and len(io.regs.mixer.group) == 4
    assert io.values(PageNo.FAILSAFE_PWM) == (1500,) * 4 + (0,) * 4


def test_mixer_upload_error_and_gating(io: Io) -> None:
    upload(io, "R: 5x 10000 10000 10000 0\n")
    assert not io.regs.status_flags & StatusFlags.MIXER_OK
    assert "geometry" in io.regs.mixer.last_error.message
    upload(io, "M: 1\nO: 10000 10000 0 -10000 10000\n" + "S: 0 0\n")
    assert not io.regs.status_flags & StatusFlags.MIXER_OK
    io.regs.status_flags |= StatusFlags.SAFETY_OFF
    assert upload(io, QUAD_X) == [OK, OK]  # dropped while safety is off
    assert not io.regs.status_flags & StatusFlags.MIXER_OK
    io.regs.status_flags |= StatusFlags.OUTPUTS_ARMED
    assert upload(io, QUAD_X) == [ERR, ERR]


def test_mixer_upload_overflow_clears_mixer_ok(io: Io) -> None:
    """A simple mixer whose text exceeds the 256-byte buffer can never complete in E14."""
    big = "M: 10\nO: 10000 10000 0 -10000 10000\n" + "".join(
        f"S: 0 {i % 8} 10000 10000 0 -10000 10000\n" for i in range(10))
    assert len(big) > 256
    upload(io, QUAD_X)
    assert io.regs.status_flags & StatusFlags.MIXER_OK
    upload(io, big)
    assert not io.regs.status_flags & StatusFlags.MIXER_OK
    assert len(io.regs.mixer.text) < 256 and len(io.regs.mixer.group) == 0


# -- issue 18, defect 10b: the mixer-derived failsafe is E14's unclamped arithmetic ----------

def test_mixer_failsafe_is_not_clamped_as_on_the_real_io(io: Io) -> None:
    """px4iofirmware mixer_set_failsafe stores outputs * 600 + 1500 without a clamp: an output
    scaler allowing 50.0 gives 31500 us (only FMU writes of page 55 are clamped)."""
    upload(io, "M: 0\nO: 10000 10000 500000 -10000 500000\n")
    assert io.regs.status_flags & StatusFlags.MIXER_OK
    assert io.values(PageNo.FAILSAFE_PWM) == (31500,) + (0,) * 7
    upload(io, "M: 0\nO: 10000 10000 -500000 -500000 10000\n")
    assert io.values(PageNo.FAILSAFE_PWM) == (0,) * 8  # -28500: a negative float gives 0
    # 70000.02 converts to the uint32 70000, then keeps its low 16 bits: 70000 - 65536
    upload(io, "M: 0\nO: 10000 10000 1141667 -10000 1141667\n")
    assert io.values(PageNo.FAILSAFE_PWM)[0] == 4464
    # 10**40 - 1 is read as the int sscanf stores: -1 (mod 2**32), i.e. offset -0.0001
    upload(io, "M: 0\nO: 10000 10000 " + "9" * 40 + " -10000 " + "9" * 40 + "\n")
    assert io.regs.status_flags & StatusFlags.MIXER_OK
    assert io.values(PageNo.FAILSAFE_PWM)[0] == 1499  # int(-0.0001 * 600 + 1500)


def test_mixer_failsafe_of_a_nan_or_infinite_output_never_raises(io: Io) -> None:
    from ioproc.mixer.base import Scaler, SimpleMixer

    upload(io, "Z:\n")
    for offset, want in ((math.nan, 0), (math.inf, 0xFFFF), (-math.inf, 0)):
        io.regs.mixer.group.reset()
        io.regs.mixer.group.add(SimpleMixer(Scaler(offset=offset, min_output=-math.inf,
                                                   max_output=math.inf), ()))
        io.regs.update_mixer_failsafe()
        assert io.values(PageNo.FAILSAFE_PWM)[0] == want


@pytest.mark.parametrize("value, stored", [
    (1500.9, 1500), (0.0, 0), (-0.0, 0), (0.99, 0), (-0.5, 0), (-28500.0, 0),
    (65535.0, 65535), (65536.0, 0), (70000.02, 4464), (2.0 ** 32 - 1, 0xFFFF),
    (2.0 ** 31 + 7, 7), (2.0 ** 32, 0xFFFF), (1e39, 0xFFFF), (math.inf, 0xFFFF),
    (-math.inf, 0), (math.nan, 0), (-math.nan, 0),
])
def test_failsafe_float_to_uint16_is_the_soft_float_conversion_then_truncation(value, stored):
    """The IO's ``uint16_t = float`` is libgcc's __aeabi_f2uiz (negative or NaN: 0; 2**32 or
    more: 0xFFFFFFFF; else toward zero), then the low 16 bits."""
    assert _float_to_u16(value) == stored
