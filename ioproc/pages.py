"""The IO's register pages as data (per era), and the firmware rules applied to each write.

Facts: io-and-rc.md §2 (page map, per-page registers, write rules) and §3 where a write has a
side effect (safety, arming, PWM rates, reboot). The table :data:`PAGE_TABLES` says, per era,
which pages exist, their registers (name, reset value), how a write is applied, and which
pages are rebuilt at read time; :class:`IoPages` holds the live values and implements the
named write hooks. It is the :class:`ioproc.protocol.PageStore` the request handler uses.

The IO's register space is its own kind: 16-bit registers in numbered pages, written through
per-page rules by a link protocol. A device's byte-wide register map is the other kind, declared
with ``peripherals.regs`` (``Reg``, ``Field``, ``RegisterFile``); the two share no code and,
since the pages were renamed from ``RegisterFile``, no name.

Two write paths, as in the firmware (``registers_set``):

* bulk pages (CONTROLS, DIRECT_PWM, the PWM value pages, MIXERLOAD) take the whole packet;
  registers past the page's end are dropped silently;
* every other page goes register by register: offset + count is first truncated at 255, each
  register's hook runs in order, and the first refused register ends the write with ERROR;
  those before it stay applied. Pages without hooks (CONFIG, SERVOS, unknown pages) refuse
  their first register - so a zero-length write to them answers SUCCESS, a faithful quirk.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

from ioproc.mixer import MixerUpload, zero_source
from ioproc.protocol import (  # noqa: F401 - register names re-exported for the IO firmware
    ARMING_LAYOUT,
    CONTROL_CHANNELS,
    CONTROL_GROUPS,
    ERA,
    FORCE_SAFETY_MAGIC,
    MAX_TRANSFER_LEN,
    PROTOCOL_VERSION,
    PWM_IGNORE_THIS_CHANNEL,
    RC_ASSIGN_MODESWITCH,
    RC_ASSIGN_UNASSIGNED,
    RC_CONFIG_STRIDE,
    RC_INPUT_CHANNELS,
    RC_OPTIONS_ENABLED,
    RC_OPTIONS_REVERSE,
    REBOOT_BL_MAGIC,
    REBOOT_DELAY_US,
    SERVO_COUNT,
    Alarms,
    Arming,
    ArmingA,
    Config,
    Era,
    Features,
    PageNo,
    RawRc,
    RawRcFlags,
    RcConfig,
    RcInput,
    Setup,
    Status,
    StatusFlags,
)


@dataclass(frozen=True)
class PwmConstants:
    """drv_pwm_output.h limits used to clamp the PWM value pages."""

    lowest_min: int
    default_min: int
    highest_min: int
    lowest_max: int
    default_max: int
    highest_max: int


PWM_CONSTANTS: dict[Era, PwmConstants] = {Era.E14: PwmConstants(900, 1000, 1300, 1700, 2000,
                                                                 2100)}
#: SETUP mask of valid FEATURES / ARMING / PWM_RATES bits per era.
FEATURES_VALID: dict[Era, int] = {Era.E14: 0x0F}
ARMING_VALID: dict[Era, int] = {Era.E14: 0x7FF}
RATES_VALID = (1 << SERVO_COUNT) - 1
#: Clamp of PWM_DEFAULTRATE / PWM_ALTRATE writes (E14, until 2015-04).
RATE_CLAMP_HZ: dict[Era, tuple[int, int]] = {Era.E14: (50, 400)}
#: Output masks of the IOv2 timer groups (TIM2, TIM3, TIM4); PWM_INFO reg g.
IOV2_RATE_GROUPS: tuple[int, ...] = (0x03, 0xF0, 0x0C, 0, 0, 0, 0, 0)


# --- the tables ------------------------------------------------------------------------------
@dataclass(frozen=True)
class RegSpec:
    name: str
    reset: int = 0


IGNORE = "ignore"  #: write hook name: accept the register and do nothing


@dataclass(frozen=True)
class PageSpec:
    """One page: readable registers (their count is the page length), and how writes land."""

    number: int
    name: str
    regs: tuple[RegSpec, ...] = ()
    readable: bool = True
    bulk_write: str | None = None  # hook taking (offset, values, now_us) -> ok
    writes: Mapping[int, str] = field(default_factory=dict)  # per-register hooks by offset
    default_write: str | None = None  # hook for offsets not in ``writes``; None -> ERROR
    refresh: str | None = None  # rebuilds the values just before a read
    storage: int | None = None  # read another page's values (E14 DIRECT_PWM -> SERVOS)

    @property
    def length(self) -> int:
        return len(self.regs)

    def write_hook(self, offset: int) -> str | None:
        """Hook name a write to ``offset`` runs (bulk pages: their bulk hook); None = ERROR."""
        if self.bulk_write is not None:
            return self.bulk_write
        return self.writes.get(offset, self.default_write)

    def access(self, offset: int) -> str:
        """"rw", "r" (read-only), "w" (write-only), "r+ignored", "ignored" or "" (none)."""
        readable = self.readable and offset < self.length
        hook = self.write_hook(offset)
        if hook == IGNORE:
            return "r+ignored" if readable else "ignored"
        return ("r" if readable else "") + ("w" if hook is not None else "")


def _regs(*names: str, resets: Mapping[str, int] | None = None) -> tuple[RegSpec, ...]:
    resets = resets or {}
    return tuple(RegSpec(n, resets.get(n, 0)) for n in names)


def _array(prefix: str, count: int, reset: int = 0) -> tuple[RegSpec, ...]:
    return tuple(RegSpec(f"{prefix}{i}", reset) for i in range(count))


def _rc_config_regs() -> tuple[RegSpec, ...]:
    regs = []
    for ch in range(RC_INPUT_CHANNELS):
        resets = (1000, 1500, 2000, 30, ch, RC_OPTIONS_ENABLED)
        regs += [RegSpec(f"RC{ch + 1}_{f.name}", r) for f, r in zip(RcConfig, resets)]
    return tuple(regs)


def _e14_pages() -> dict[int, PageSpec]:
    e14 = Era.E14
    setup_writes: dict[int, str] = {Setup.FEATURES: "features", Setup.ARMING: "arming",
                    Setup.PWM_RATES: "pwm_rates", Setup.PWM_DEFAULTRATE: "pwm_defaultrate",
                    Setup.PWM_ALTRATE: "pwm_altrate", Setup.VSERVO_SCALE: "store",
                    Setup.DSM: "dsm", Setup.SET_DEBUG: "store", Setup.REBOOT_BL: "reboot_bl",
                    Setup.FORCE_SAFETY_OFF: "force_safety_off",
                    Setup.RC_THR_FAILSAFE_US: "rc_thr_failsafe",
                    Setup.FORCE_SAFETY_ON: "force_safety_on"}
    pages = [
        PageSpec(PageNo.CONFIG, "CONFIG", _regs(*Config.__members__, resets={
            "PROTOCOL_VERSION": PROTOCOL_VERSION[e14], "HARDWARE_VERSION": 2,
            "BOOTLOADER_VERSION": 3, "MAX_TRANSFER": MAX_TRANSFER_LEN, "CONTROL_COUNT": 8,
            "ACTUATOR_COUNT": SERVO_COUNT, "RC_INPUT_COUNT": RC_INPUT_CHANNELS,
            "ADC_INPUT_COUNT": 2, "RELAY_COUNT": 0})),
        PageSpec(PageNo.STATUS, "STATUS", _regs(*Status.__members__), refresh="status",
                 writes={Status.FLAGS: "status_flags", Status.ALARMS: "status_alarms"},
                 default_write=IGNORE),
        PageSpec(PageNo.ACTUATORS, "ACTUATORS", _array("ACTUATOR", SERVO_COUNT)),
        PageSpec(PageNo.SERVOS, "SERVOS", _array("SERVO", SERVO_COUNT)),
        PageSpec(PageNo.RAW_RC_INPUT, "RAW_RC_INPUT",
                 _regs(*list(RawRc.__members__)[:-1]) + _array("RC_CHANNEL", 19)),
        PageSpec(PageNo.RC_INPUT, "RC_INPUT", _regs("VALID") + _array("CONTROL", 9)),
        PageSpec(PageNo.RAW_ADC_INPUT, "RAW_ADC_INPUT", _array("ADC", 32), refresh="raw_adc"),
        PageSpec(PageNo.PWM_INFO, "PWM_INFO", _array("RATE_MAP", 32), refresh="pwm_info"),
        PageSpec(PageNo.SETUP, "SETUP", _regs(
            *list(Setup.__members__)[:13], "RC_THR_FAILSAFE_US", resets={
                "FEATURES": Features.ADC_RSSI, "PWM_DEFAULTRATE": 50, "PWM_ALTRATE": 200,
                "VSERVO_SCALE": 10000}), writes=setup_writes),
        PageSpec(PageNo.CONTROLS, "CONTROLS", _array("CONTROL", CONTROL_GROUPS *
                                                     CONTROL_CHANNELS), bulk_write="controls"),
        PageSpec(PageNo.MIXERLOAD, "MIXERLOAD", readable=False, bulk_write="mixerload"),
        PageSpec(PageNo.RC_CONFIG, "RC_CONFIG", _rc_config_regs(), default_write="rc_config"),
        PageSpec(PageNo.DIRECT_PWM, "DIRECT_PWM", _array("PWM", SERVO_COUNT),
                 bulk_write="direct_pwm", storage=PageNo.SERVOS),
        PageSpec(PageNo.FAILSAFE_PWM, "FAILSAFE_PWM", _array("PWM", SERVO_COUNT),
                 bulk_write="failsafe_pwm"),
        PageSpec(PageNo.CONTROL_MIN_PWM, "CONTROL_MIN_PWM", _array("PWM", SERVO_COUNT, 1000),
                 bulk_write="control_min_pwm"),
        PageSpec(PageNo.CONTROL_MAX_PWM, "CONTROL_MAX_PWM", _array("PWM", SERVO_COUNT, 2000),
                 bulk_write="control_max_pwm"),
        PageSpec(PageNo.DISARMED_PWM, "DISARMED_PWM", _array("PWM", SERVO_COUNT),
                 bulk_write="disarmed_pwm"),
        PageSpec(PageNo.TEST, "TEST", readable=False, writes={0: "test_led"},
                 default_write=IGNORE),
    ]
    return {p.number: p for p in pages}


#: era -> page number -> page description.
PAGE_TABLES: dict[Era, dict[int, PageSpec]] = {Era.E14: _e14_pages()}


# --- hardware the register side effects reach -----------------------------------------------
def _accept_rate(group: int, rate_hz: int) -> bool:
    return 1 <= rate_hz <= 10000  # PWM_RATE_LOWER/UPPER_LIMIT of the timer layer


@dataclass
class IoHooks:
    """What register accesses touch outside the register file; the IO board wires these.

    Defaults are inert so the pages can be tested alone.
    """

    adc_measure: Callable[[int], int] = lambda channel: 0  # 12-bit counts, 0xFFFF = timeout
    freemem: Callable[[], int] = lambda: 4096  # [model] bytes free; the real heap is not modelled
    rate_group_mask: Callable[[int], int] = lambda g: IOV2_RATE_GROUPS[g]
    set_rate_group: Callable[[int, int], bool] = _accept_rate
    dsm_bind: Callable[[int, int], None] = lambda command, pulses: None
    set_sbus_out: Callable[[bool], None] = lambda enabled: None
    set_amber_led: Callable[[bool], None] = lambda on: None


ADC_VSERVO = 4  #: IOv2 ADC channel of the servo rail (PA4)
ADC_RSSI = 5  #: IOv2 ADC channel of the analog RSSI input (PA5)


def _float_to_u16(value: float) -> int:
    """A C float stored into a uint16_t register, as the IO's code does it.

    The STM32F100 has no FPU: GCC converts ``float -> uint16_t`` with libgcc's soft-float
    ``__aeabi_f2uiz`` (alias ``__fixunssfsi``, libgcc/config/arm/ieee754-sf.S, read in GCC's
    source): a value with the sign bit set (negative, -0, -inf) or a NaN gives 0, a value of
    2**32 or more (and +inf) gives 0xFFFFFFFF, anything else is truncated toward zero; the
    uint32 is then narrowed to the register's 16 bits (the low half). Out of range this is
    undefined in C; this is what that code does. The model takes the value as it computed it
    (a double); the float32 rounding of the IO's arithmetic is not modelled."""
    if math.isnan(value) or value < 0.0:
        return 0
    if value >= 4294967296.0:
        return 0xFFFF  # 0xFFFFFFFF, narrowed
    return int(value) & 0xFFFF


class _PageReg:
    """One register of a page as an attribute of :class:`IoPages` (the firmware's named
    registers): reads the live value, stores what a uint16 register keeps."""

    def __init__(self, page: int, offset: int) -> None:
        self.page = page
        self.offset = offset

    def __get__(self, pages: IoPages, owner: type | None = None) -> int:
        return pages.values[self.page][self.offset]

    def __set__(self, pages: IoPages, value: int) -> None:
        pages.values[self.page][self.offset] = int(value) & 0xFFFF


class IoPages:
    """Live register pages of one IO, with the era's write rules (a ``PageStore``)."""

    def __init__(self, era: Era = ERA, hooks: IoHooks | None = None, firmware_crc: int = 0):
        self.era = era
        self.spec = PAGE_TABLES[era]
        self.hooks = hooks or IoHooks()
        self.pwm = PWM_CONSTANTS[era]
        self.values: dict[int, list[int]] = {
            p.number: [r.reset for r in p.regs] for p in self.spec.values() if p.storage is None}
        setup = self.values[PageNo.SETUP]
        setup[Setup.CRC] = firmware_crc & 0xFFFF
        setup[Setup.CRC_HIGH] = (firmware_crc >> 16) & 0xFFFF
        self.mixer = MixerUpload(era)
        self.fmu_data_received_us: int | None = None  # set by CONTROLS / DIRECT_PWM writes
        self.reboot_at_us: int | None = None  # scheduled reset after REBOOT_BL magic

    # -- convenience for the IO firmware ------------------------------------------------------
    def page(self, number: int) -> list[int]:
        """The live value list of a page (writes to it bypass the rules: firmware-internal)."""
        spec = self.spec[number]
        return self.values[spec.storage if spec.storage is not None else number]

    status_flags = _PageReg(PageNo.STATUS, Status.FLAGS)
    alarms = _PageReg(PageNo.STATUS, Status.ALARMS)
    arming = _PageReg(PageNo.SETUP, Setup.ARMING)

    # -- PageStore -----------------------------------------------------------------------
    def read(self, page: int, offset: int) -> Sequence[int] | None:
        """registers_get: values from ``offset`` to the page end; None -> ERROR reply."""
        spec = self.spec.get(page)
        if spec is None or not spec.readable:
            return None
        if spec.refresh is not None:
            getattr(self, "_refresh_" + spec.refresh)()
        values = self.values[spec.storage if spec.storage is not None else page]
        if offset >= len(values):
            return None
        return values[offset:]

    def write(self, page: int, offset: int, values: Sequence[int], now_us: int) -> bool:
        """registers_set: apply in order; False (ERROR) at the first refused register."""
        spec = self.spec.get(page)
        if spec is not None and spec.bulk_write is not None:
            return getattr(self, "_bulk_" + spec.bulk_write)(offset, values, now_us)
        count = len(values)
        if offset + count > 255:  # avoid offset wrap; register 255 itself is never written
            count = 255 - offset
        for i in range(count):
            reg = offset + i
            hook = None if spec is None else spec.write_hook(reg)
            if hook is None:
                return False
            if hook != IGNORE and not getattr(self, "_w_" + hook)(page, reg, values[i], now_us):
                return False
        return True

    # -- read-time refresh -------------------------------------------------------------------
    def _refresh_status(self) -> None:
        status = self.values[PageNo.STATUS]
        status[Status.FREEMEM] = self.hooks.freemem() & 0xFFFF
        counts = self.hooks.adc_measure(ADC_VSERVO)
        if counts != 0xFFFF:
            status[Status.VSERVO] = counts * 9900 // 4096  # 3:1 divider on a 3.3 V ADC
        counts = self.hooks.adc_measure(ADC_RSSI)
        if counts != 0xFFFF:
            status[Status.VRSSI] = counts * 3300 // 4096

    def _refresh_raw_adc(self) -> None:
        scratch = self.values[PageNo.RAW_ADC_INPUT]
        scratch[:] = [0] * len(scratch)
        scratch[0] = self.hooks.adc_measure(ADC_VSERVO) & 0xFFFF
        scratch[1] = self.hooks.adc_measure(ADC_RSSI) & 0xFFFF

    def _refresh_pwm_info(self) -> None:
        scratch = self.values[PageNo.PWM_INFO]
        scratch[:] = [0] * len(scratch)
        for group in range(SERVO_COUNT):
            scratch[group] = self.hooks.rate_group_mask(group) & 0xFFFF

    # -- bulk pages --------------------------------------------------------------------------
    def _bulk_controls(self, offset: int, values: Sequence[int], now_us: int) -> bool:
        controls = self.values[PageNo.CONTROLS]
        for v in values:
            if offset >= len(controls):
                break
            controls[offset] = v
            offset += 1
        self.fmu_data_received_us = now_us
        self.status_flags = (self.status_flags | StatusFlags.FMU_OK) & ~StatusFlags.RAW_PWM
        return True

    def _bulk_direct_pwm(self, offset: int, values: Sequence[int], now_us: int) -> bool:
        servos = self.values[PageNo.SERVOS]
        for v in values:
            if offset >= SERVO_COUNT:
                break
            if v != PWM_IGNORE_THIS_CHANNEL:
                servos[offset] = v
            offset += 1
        self.fmu_data_received_us = now_us
        self.status_flags |= StatusFlags.FMU_OK | StatusFlags.RAW_PWM
        return True

    def _clamped_store(self, page: int, offset: int, values: Sequence[int], lo: int, hi: int,
                       on_each: Callable[[int], None] | None = None) -> None:
        """Store clamped values, 0 = leave unchanged; ``on_each`` runs per register taken."""
        target = self.values[page]
        for v in values:
            if offset >= SERVO_COUNT:
                break
            if v != 0:
                target[offset] = lo if v < lo else (min(v, hi))
            if on_each is not None:
                on_each(v)
            offset += 1

    def _bulk_failsafe_pwm(self, offset: int, values: Sequence[int], now_us: int) -> bool:
        def custom(_: int) -> None:
            self.arming |= Arming.FAILSAFE_CUSTOM  # any register written, even 0

        self._clamped_store(PageNo.FAILSAFE_PWM, offset, values, self.pwm.lowest_min,
                            self.pwm.highest_max, custom)
        return True

    def _bulk_control_min_pwm(self, offset: int, values: Sequence[int], now_us: int) -> bool:
        self._clamped_store(PageNo.CONTROL_MIN_PWM, offset, values, self.pwm.lowest_min,
                            self.pwm.highest_min)
        return True

    def _bulk_control_max_pwm(self, offset: int, values: Sequence[int], now_us: int) -> bool:
        self._clamped_store(PageNo.CONTROL_MAX_PWM, offset, values, self.pwm.lowest_max,
                            self.pwm.highest_max)
        return True

    def _bulk_disarmed_pwm(self, offset: int, values: Sequence[int], now_us: int) -> bool:
        disarmed = self.values[PageNo.DISARMED_PWM]
        lo, hi = self.pwm.lowest_min, self.pwm.highest_max
        all_off = True
        for v in values:
            if offset >= SERVO_COUNT:
                break
            if v == 0:
                disarmed[offset] = 0  # "no pulse" while disarmed
            else:
                disarmed[offset] = lo if v < lo else (min(v, hi))
                all_off = False
            offset += 1
        if all_off:  # also for a write that stored nothing: a faithful quirk
            self.arming &= ~Arming.ALWAYS_PWM_ENABLE
        else:
            self.arming |= Arming.ALWAYS_PWM_ENABLE
        return True

    def _bulk_mixerload(self, offset: int, values: Sequence[int], now_us: int) -> bool:
        flags = self.status_flags
        if flags & StatusFlags.SAFETY_OFF:  # no mixer change on an active system
            return not flags & StatusFlags.OUTPUTS_ARMED
        result = self.mixer.handle(values)
        if result.mixer_ok is not None:
            if result.mixer_ok:
                self.status_flags |= StatusFlags.MIXER_OK
            else:
                self.status_flags &= ~StatusFlags.MIXER_OK
        if result.parsed:
            self.update_mixer_failsafe()
        return True

    def update_mixer_failsafe(self) -> None:
        """mixer_set_failsafe: FAILSAFE_PWM = zero-input mix x600 + 1500, unless custom.

        Not clamped, as on the real IO: px4iofirmware/mixer.cpp mixer_set_failsafe (E14 and
        every later version with a mixer on the IO) stores ``(outputs[i] * 600.0f) + 1500``
        straight into the uint16 register, with no PWM_LOWEST_MIN/HIGHEST_MAX clamp (that clamp
        is only applied to FMU writes of page 55) and no servo limits. The mixer's outputs are
        bounded only by its scalers' limits, which the parser does not range-check, so a mixer
        with ``O: ... 500000`` gives 50.0 and a failsafe of 31500 us, and a failsafe output then
        drives the timer's compare register with it (a pulse longer than the PWM period: the
        pin stays high). The float-to-uint16 conversion of a value outside 0..65535 is undefined
        in C; modelled as the soft-float code does it (:func:`_float_to_u16`): negative or NaN
        gives 0, 70000 gives 4464 (the low 16 bits), 2**32 or more 0xFFFF.
        """
        if self.arming & Arming.FAILSAFE_CUSTOM or not self.status_flags & StatusFlags.MIXER_OK:
            return
        outputs = self.mixer.group.mix(zero_source, SERVO_COUNT)
        failsafe = self.values[PageNo.FAILSAFE_PWM]
        for i in range(SERVO_COUNT):
            failsafe[i] = _float_to_u16(outputs[i] * 600.0 + 1500) if i < len(outputs) else 0

    # -- per-register hooks: (page, offset, value, now_us) -> accepted -----------------------
    def _w_store(self, page: int, reg: int, value: int, now_us: int) -> bool:
        self.values[page][reg] = value
        return True

    def _w_status_flags(self, page: int, reg: int, value: int, now_us: int) -> bool:
        if not self.status_flags & StatusFlags.ARM_SYNC:  # FMU may restore state until synced
            self.status_flags = value
        return True

    def _w_status_alarms(self, page: int, reg: int, value: int, now_us: int) -> bool:
        self.alarms &= ~value
        return True

    def _w_features(self, page: int, reg: int, value: int, now_us: int) -> bool:
        value &= FEATURES_VALID[self.era]
        self.hooks.set_sbus_out(bool(value & (Features.SBUS1_OUT | Features.SBUS2_OUT)))
        if value & Features.SBUS1_OUT:
            value &= ~(Features.PWM_RSSI | Features.ADC_RSSI | Features.SBUS2_OUT)
        if value & Features.SBUS2_OUT:
            value &= ~(Features.PWM_RSSI | Features.ADC_RSSI | Features.SBUS1_OUT)
        if value & Features.ADC_RSSI:
            value &= ~(Features.PWM_RSSI | Features.SBUS1_OUT | Features.SBUS2_OUT)
        if value & Features.PWM_RSSI:
            value &= ~(Features.ADC_RSSI | Features.SBUS1_OUT | Features.SBUS2_OUT)
        self.values[page][reg] = int(value)
        return True

    def _w_arming(self, page: int, reg: int, value: int, now_us: int) -> bool:
        value &= ARMING_VALID[self.era]
        if value & Arming.RC_HANDLING_DISABLED:
            self.status_flags |= StatusFlags.INIT_OK
        old = self.arming
        value |= old & Arming.TERMINATION_FAILSAFE  # sticky once set
        if old & Arming.TERMINATION_FAILSAFE:
            value |= old & Arming.FORCE_FAILSAFE
        self.arming = value
        return True

    def _configure_rates(self, rates: int, default_hz: int, alt_hz: int) -> None:
        """pwm_configure_rates: check every group, then program them with the *stored* rates."""
        setup = self.values[PageNo.SETUP]
        masks = [self.hooks.rate_group_mask(g) for g in range(SERVO_COUNT)]
        for mask in masks:
            alt = rates & mask
            if mask and alt and alt != mask:  # a group must be all-default or all-alternate
                self.alarms |= Alarms.PWM_ERROR
                return
        for group, mask in enumerate(masks):
            if not mask:
                continue
            hz = setup[Setup.PWM_ALTRATE] if rates & mask else setup[Setup.PWM_DEFAULTRATE]
            if not self.hooks.set_rate_group(group, hz):
                self.alarms |= Alarms.PWM_ERROR
        setup[Setup.PWM_RATES] = rates
        setup[Setup.PWM_DEFAULTRATE] = default_hz
        setup[Setup.PWM_ALTRATE] = alt_hz

    def _clamp_rate(self, value: int) -> int:
        lo, hi = RATE_CLAMP_HZ[self.era]
        return lo if value < lo else (min(value, hi))

    def _w_pwm_rates(self, page: int, reg: int, value: int, now_us: int) -> bool:
        setup = self.values[PageNo.SETUP]
        self._configure_rates(value & RATES_VALID, setup[Setup.PWM_DEFAULTRATE],
                              setup[Setup.PWM_ALTRATE])
        return True

    def _w_pwm_defaultrate(self, page: int, reg: int, value: int, now_us: int) -> bool:
        setup = self.values[PageNo.SETUP]
        self._configure_rates(setup[Setup.PWM_RATES], self._clamp_rate(value),
                              setup[Setup.PWM_ALTRATE])
        return True

    def _w_pwm_altrate(self, page: int, reg: int, value: int, now_us: int) -> bool:
        setup = self.values[PageNo.SETUP]
        self._configure_rates(setup[Setup.PWM_RATES], setup[Setup.PWM_DEFAULTRATE],
                              self._clamp_rate(value))
        return True

    def _w_dsm(self, page: int, reg: int, value: int, now_us: int) -> bool:
        self.hooks.dsm_bind(value & 0x0F, (value >> 4) & 0x0F)  # not stored
        return True

    def _w_reboot_bl(self, page: int, reg: int, value: int, now_us: int) -> bool:
        flags = self.status_flags
        if flags & (StatusFlags.SAFETY_OFF | StatusFlags.OUTPUTS_ARMED):
            return True  # never while armed; still acknowledged
        if value == REBOOT_BL_MAGIC:
            self.reboot_at_us = now_us + REBOOT_DELAY_US  # lets the IO acknowledge first
        return True

    def _w_force_safety_off(self, page: int, reg: int, value: int, now_us: int) -> bool:
        if value == FORCE_SAFETY_MAGIC:  # E14 ignores other values (E19 answers ERROR)
            self.status_flags |= StatusFlags.SAFETY_OFF
        return True

    def _w_force_safety_on(self, page: int, reg: int, value: int, now_us: int) -> bool:
        if value == FORCE_SAFETY_MAGIC:
            self.status_flags &= ~StatusFlags.SAFETY_OFF
        return True

    def _w_rc_thr_failsafe(self, page: int, reg: int, value: int, now_us: int) -> bool:
        if 650 < value < 2350:
            self.values[page][reg] = value
        return True

    def _w_rc_config(self, page: int, reg: int, value: int, now_us: int) -> bool:
        if self.status_flags & (StatusFlags.SAFETY_OFF | StatusFlags.OUTPUTS_ARMED):
            return True  # no RC config change on an active system; still SUCCESS
        channel, index = divmod(reg, RC_CONFIG_STRIDE)
        if channel >= RC_INPUT_CHANNELS:
            return False
        conf = self.values[PageNo.RC_CONFIG]
        base = channel * RC_CONFIG_STRIDE
        conf[base + RcConfig.OPTIONS] &= RC_OPTIONS_ENABLED  # REVERSE dropped until re-written
        if index != RcConfig.OPTIONS:
            conf[base + index] = value
            return True
        value &= RC_OPTIONS_ENABLED | RC_OPTIONS_REVERSE
        self.status_flags |= StatusFlags.INIT_OK
        self.arming &= ~Arming.RC_HANDLING_DISABLED
        conf[base + RcConfig.OPTIONS] = value & ~RC_OPTIONS_ENABLED
        if value & RC_OPTIONS_ENABLED:
            c_min, c_center, c_max, c_dz, c_assign = conf[base:base + RcConfig.OPTIONS]
            errors = sum((c_min < 500, c_max > 2500, c_center < c_min, c_center > c_max,
                          c_dz > 500))
            if c_assign >= CONTROL_CHANNELS and c_assign not in (RC_ASSIGN_MODESWITCH,
                                                                 RC_ASSIGN_UNASSIGNED):
                errors += 1
            if errors:
                self.status_flags &= ~StatusFlags.INIT_OK
            elif c_assign != RC_ASSIGN_UNASSIGNED:
                conf[base + RcConfig.OPTIONS] |= RC_OPTIONS_ENABLED
        return True

    def _w_test_led(self, page: int, reg: int, value: int, now_us: int) -> bool:
        self.hooks.set_amber_led(bool(value & 1))
        return True
