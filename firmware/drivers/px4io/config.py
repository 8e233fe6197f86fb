"""What the px4io driver writes to the IO, computed from parameters and files (no link here).

Kept apart from the task so the tables (RC_CONFIG per channel, PWM pages, the mixer chunks,
the CONFIG sanity limits) can be read and tested as plain data.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Final

from firmware.drivers.px4io.params import CBRK_IO_SAFETY_KEY, RC_DEFAULTS, rc_param_defaults
from ioproc.mixer import encode_mixer_upload, filter_mixer_file
from ioproc.protocol import (
    RC_ASSIGN_MODESWITCH,
    RC_ASSIGN_UNASSIGNED,
    RC_OPTIONS_ENABLED,
    RC_OPTIONS_REVERSE,
    Config,
    Features,
    PageNo,
)

if TYPE_CHECKING:
    from firmware.system import System

__all__ = ["ALARM_FIELDS", "ARMING_FIELDS", "CBRK_IO_SAFETY_KEY", "CONFIG_READS",
           "DEFAULT_RATE_HZ", "FEATURES", "STATUS_FIELDS", "check_config", "mixer_chunks",
           "mixer_path", "output_mask", "pad8", "pwm_pages", "rc_config_table"]

ParamGetter = Callable[[str, float], float]

#: CONFIG registers read after the protocol version, in the E14 order (§1.8 "Init sequence").
CONFIG_READS: Final[tuple[tuple[str, int], ...]] = (
    ("hardware", Config.HARDWARE_VERSION), ("actuators", Config.ACTUATOR_COUNT),
    ("controls", Config.CONTROL_COUNT), ("relays", Config.RELAY_COUNT),
    ("max_transfer", Config.MAX_TRANSFER), ("rc_inputs", Config.RC_INPUT_COUNT),
    ("bootloader", Config.BOOTLOADER_VERSION))

FEATURES: Final = int(Features.ADC_RSSI)  #: analog RSSI on PA5, the IO's reset value, made explicit
DEFAULT_RATE_HZ: Final = 50

STATUS_FIELDS: Final[tuple[str, ...]] = ("ARM_SYNC", "FAILSAFE", "FMU_INITIALIZED", "FMU_OK", "INIT_OK",
                 "OUTPUTS_ARMED", "OVERRIDE", "RAW_PWM", "RC_OK", "RC_DSM", "RC_PPM", "RC_SBUS",
                 "RC_ST24", "RC_SUMD", "SAFETY_OFF")
ALARM_FIELDS: Final[tuple[str, ...]] = ("FMU_LOST", "PWM_ERROR", "RC_LOST", "SERVO_CURRENT", "TEMPERATURE",
                "VSERVO_FAULT")
ARMING_FIELDS: Final[tuple[str, ...]] = ("FAILSAFE_CUSTOM", "FMU_ARMED", "FORCE_FAILSAFE", "IO_ARM_OK", "LOCKDOWN",
                 "TERMINATION_FAILSAFE")


def check_config(c: dict[str, int]) -> str:
    """E14's sanity limits on CONFIG; the problem, or "" when the IO looks sane."""
    if not 1 <= c["actuators"] <= 255:
        return f"{c['actuators']} actuators (1..255)"
    if c["relays"] > 32:
        return f"{c['relays']} relays (at most 32)"
    if not 16 <= c["max_transfer"] - 2 <= 255:
        return f"max transfer {c['max_transfer']} bytes (18..257)"
    if not 1 <= c["rc_inputs"] <= 255:
        return f"{c['rc_inputs']} RC inputs (1..255)"
    return ""


def output_mask(digits: int) -> int:
    """PWM_OUT as the script wrote it (1234 = outputs 1..4) -> SETUP_PWM_RATES bit mask."""
    mask = 0
    for ch in str(max(0, digits)):
        if "1" <= ch <= "8":
            mask |= 1 << (int(ch) - 1)
    return mask


def pwm_pages(param: ParamGetter, n: int) -> tuple[tuple[int, tuple[int, ...]], ...]:
    """(page, values) writes: CONTROL_MIN, CONTROL_MAX, FAILSAFE if any set, DISARMED."""
    pages = [(int(PageNo.CONTROL_MIN_PWM), (int(param("PWM_MIN", 1000)),) * n),
             (int(PageNo.CONTROL_MAX_PWM), (int(param("PWM_MAX", 2000)),) * n)]
    fails = [int(param(f"PWM_MAIN_FAIL{i + 1}", -1)) for i in range(n)]
    if any(v > 0 for v in fails):  # any write makes the IO drop its mixer-derived values
        pages.append((int(PageNo.FAILSAFE_PWM), tuple(max(v, 0) for v in fails)))
    disarmed = int(param("PWM_DISARMED", 900))
    dis = [int(param(f"PWM_MAIN_DIS{i + 1}", -1)) for i in range(n)]
    pages.append((int(PageNo.DISARMED_PWM), tuple(v if v >= 0 else disarmed for v in dis)))
    return tuple(pages)


def rc_config_table(param: ParamGetter, channels: int) -> list[list[int]]:
    """RC_CONFIG registers per channel from RCn_* and RC_MAP_* (E14 io_set_rc_config)."""
    assign: dict[int, int] = {}
    for name, code in (("RC_MAP_ROLL", 0), ("RC_MAP_PITCH", 1), ("RC_MAP_YAW", 2),
                       ("RC_MAP_THROTTLE", 3), ("RC_MAP_FLAPS", 4),
                       ("RC_MAP_MODE_SW", RC_ASSIGN_MODESWITCH)):
        ch = int(param(name, RC_DEFAULTS[name]))
        if ch > 0:
            assign[ch - 1] = code
    table = []
    for c in range(channels):
        d = rc_param_defaults(c + 1)
        n = c + 1
        rev = param(f"RC{n}_REV", d[f"RC{n}_REV"])
        options = RC_OPTIONS_ENABLED | (RC_OPTIONS_REVERSE if rev < 0 else 0)
        table.append([int(param(f"RC{n}_MIN", d[f"RC{n}_MIN"])),
                      int(param(f"RC{n}_TRIM", d[f"RC{n}_TRIM"])),
                      int(param(f"RC{n}_MAX", d[f"RC{n}_MAX"])),
                      int(param(f"RC{n}_DZ", d[f"RC{n}_DZ"])),
                      assign.get(c, RC_ASSIGN_UNASSIGNED), options])
    return table


def mixer_path(system: System, name: str) -> str:
    """A mixer name -> FMU path: absolute paths as given, else /etc/mixers/NAME[.main.mix]."""
    if name.startswith("/"):
        candidates = [name]
    else:
        candidates = [f"/etc/mixers/{name}"]
        if not name.endswith(".mix"):
            candidates.append(f"/etc/mixers/{name}.main.mix")
    for path in candidates:
        if system.is_file(path):
            return path
    raise FileNotFoundError(f"no such mixer file (looked for {', '.join(candidates)})")


def mixer_chunks(system: System, name: str, max_transfer: int) -> list[list[int]]:
    """The page-52 writes for a mixer file: the FMU filters the text, then chunks it."""
    path = mixer_path(system, name)
    text = system.resolve_path(path).read_text(encoding="latin-1")
    filtered = filter_mixer_file(text)
    if not filtered.strip():
        raise ValueError(f"{path}: no mixer lines in the file")
    return encode_mixer_upload(filtered, max_transfer)


def pad8(values: list[int]) -> list[int]:
    return (list(values) + [0] * 8)[:8]
