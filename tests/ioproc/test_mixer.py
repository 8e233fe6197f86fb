"""Mixer text parsing (PX4 format, E14 IO rules), mixers' outputs and saturation, upload."""

from __future__ import annotations

import math

import pytest

from ioproc.mixer import (
    GEOMETRIES,
    ROTOR_TABLES,
    MixerGroup,
    MixerParseError,
    MixerUpload,
    MultirotorMixer,
    NullMixer,
    SimpleMixer,
    encode_mixer_upload,
    filter_mixer_file,
    load_from_buf,
    parse_mixer_text,
)
from firmware.romfs import ROMFS_ROOT
from ioproc.protocol import Era

QUAD_X_FILE = """Multirotor mixer for PX4FMU
===========================

This file defines a single mixer for a quadrotor in the X configuration.  All controls
are mixed 100%.

R: 4x 10000 10000 10000 0
"""

SIMPLE_FILE = """Aileron mixer
-------------
M: 2
O:      10000  10000      0 -10000  10000
S: 0 0  10000  10000      0 -10000  10000
S: 0 2  -5000  -8000   1000 -10000  10000

Z:
"""


def controls(roll=0.0, pitch=0.0, yaw=0.0, thrust=0.0):
    values = {(0, 0): roll, (0, 1): pitch, (0, 2): yaw, (0, 3): thrust}
    return lambda group, index: values.get((group, index))


def test_parse_quad_x_file() -> None:
    (mixer,) = parse_mixer_text(QUAD_X_FILE)
    assert isinstance(mixer, MultirotorMixer) and mixer.name == "quad_x"
    assert mixer.output_count == 4 and mixer.roll_scale == 1.0 and mixer.idle_speed == 0.0


def test_parse_simple_and_null() -> None:
    simple, null = parse_mixer_text(SIMPLE_FILE)
    assert isinstance(simple, SimpleMixer) and isinstance(null, NullMixer)
    assert simple.inputs[1].group == 0 and simple.inputs[1].index == 2
    sc = simple.inputs[1].scaler
    assert (sc.negative_scale, sc.positive_scale, sc.offset) == (-0.5, -0.8, 0.1)
    assert simple.check() == 0
    # 0.4 * 1 + (0.5 * -0.8 + 0.1) = 0.1 ; negative yaw uses the negative scale
    assert simple.mix(controls(roll=0.4, yaw=0.5), 8) == [pytest.approx(0.1)]
    assert simple.mix(controls(roll=0.4, yaw=-0.5), 8) == [pytest.approx(0.75)]
    assert simple.mix(controls(roll=1.0, yaw=-1.0), 8) == [1.0]  # output limit
    assert null.mix(controls(), 8) == [0.0]


def test_unavailable_control_is_zero() -> None:
    (simple,) = parse_mixer_text("M: 1\nO: 10000 10000 0 -10000 10000\n"
                                 "S: 3 7 10000 10000 2000 -10000 10000\n")
    assert simple.mix(lambda g, i: None, 8) == [pytest.approx(0.2)]


@pytest.mark.parametrize("token, angles_deg, spins", [
    ("4x", (45, 225, 315, 135), "++--"),
    ("4+", (90, 270, 0, 180), "++--"),
    ("6x", (90, 270, 330, 150, 30, 210), "-+-++-"),
    ("6+", (0, 180, 240, 60, 300, 120), "-+-++-"),
    ("8x", (22.5, 202.5, 67.5, 157.5, 337.5, 247.5, 292.5, 112.5), "--++++--"),
    ("8+", (0, 180, 45, 135, 315, 225, 270, 90), "--++++--"),
    ("8c", (45, 315, 225, 135, 315, 45, 135, 225), "+-+-+-+-"),
    ("4h", (45, 225, 315, 135), "--++"),
])
def test_rotor_tables_follow_geometry(token, angles_deg, spins) -> None:
    """roll = -sin(a), pitch = cos(a) (a clockwise from the nose), yaw +1 CCW / -1 CW."""
    _, rotors = ROTOR_TABLES[token]
    assert len(rotors) == len(angles_deg)
    for (roll, pitch, yaw), a, s in zip(rotors, angles_deg, spins):
        assert roll == pytest.approx(-math.sin(math.radians(a)), abs=1e-5)
        assert pitch == pytest.approx(math.cos(math.radians(a)), abs=1e-5)
        assert yaw == (1.0 if s == "+" else -1.0)


def test_e14_geometry_set() -> None:
    assert {"4x", "4+", "4w", "6x", "6+", "8x", "8+"} <= GEOMETRIES[Era.E14]
    with pytest.raises(MixerParseError, match="unrecognised geometry '4h'"):
        parse_mixer_text("R: 4h 10000 10000 10000 0\n")


def quad(idle: int = 0) -> MultirotorMixer:
    (mixer,) = parse_mixer_text(f"R: 4x 10000 10000 10000 {idle}\n")
    return mixer


def as_motor(outputs):
    """-1..1 output back to 0..1 motor command (idle 0)."""
    return [(o + 1.0) / 2.0 for o in outputs]


def test_quad_x_pure_inputs() -> None:
    m = quad()
    assert m.mix(controls(thrust=0.5), 8) == [0.0] * 4
    assert m.mix(controls(), 8) == [-1.0] * 4
    k = 0.707107 * 0.1
    roll = as_motor(m.mix(controls(roll=0.1, thrust=0.5), 8))
    assert roll == pytest.approx([0.5 - k, 0.5 + k, 0.5 + k, 0.5 - k])  # left motors up
    pitch = as_motor(m.mix(controls(pitch=0.1, thrust=0.5), 8))
    assert pitch == pytest.approx([0.5 + k, 0.5 - k, 0.5 + k, 0.5 - k])  # front motors up
    yaw = as_motor(m.mix(controls(yaw=0.1, thrust=0.5), 8))
    assert yaw == pytest.approx([0.6, 0.6, 0.4, 0.4])  # CCW motors up


def test_quad_x_axis_scales() -> None:
    (m,) = parse_mixer_text("R: 4x 5000 10000 2000 0\n")
    roll = as_motor(m.mix(controls(roll=0.2, yaw=0.5, thrust=0.5), 8))
    k = 0.707107 * 0.1
    assert roll == pytest.approx([0.5 - k + 0.1, 0.5 + k + 0.1, 0.5 + k - 0.1, 0.5 - k - 0.1])


def test_saturation_low_side_keeps_thrust_drops_yaw() -> None:
    out = as_motor(quad().mix(controls(roll=1.0, yaw=0.5, thrust=0.2), 8))
    assert min(out) == pytest.approx(0.0, abs=1e-9)
    assert sum(out) / 4 == pytest.approx(0.2)
    assert out[1] == pytest.approx(out[2]) and out[0] == pytest.approx(out[3])  # no yaw


def test_saturation_high_side_scales_down() -> None:
    out = as_motor(quad().mix(controls(pitch=0.5, thrust=0.9), 8))
    assert max(out) == pytest.approx(1.0)
    top = 0.9 + 0.5 * 0.707107
    assert out[1] == pytest.approx((0.9 - 0.5 * 0.707107) / top)
    assert all(-1.0 <= o <= 1.0 for o in quad().mix(controls(1, 1, 1, 1), 8))


def test_yaw_limited_to_keep_motors_positive() -> None:
    out = as_motor(quad().mix(controls(yaw=-1.0, thrust=0.3), 8))
    assert out == pytest.approx([0.0, 0.0, 0.6, 0.6])


def test_idle_speed_and_inputs_clipped() -> None:
    assert quad(idle=1000).mix(controls(), 8) == pytest.approx([-0.8] * 4)
    assert quad().mix(controls(thrust=2.0), 8) == [1.0] * 4
    assert quad().mix(controls(thrust=-1.0), 8) == [-1.0] * 4


def test_group_fills_outputs_in_order() -> None:
    group = MixerGroup()
    for mixer in parse_mixer_text(QUAD_X_FILE + SIMPLE_FILE + "Z:\nZ:\n"):
        group.add(mixer)
    assert len(group) == 5 and group.output_count == 8
    out = group.mix(controls(roll=0.4, thrust=0.5), 8)
    assert len(out) == 8 and out[4] == pytest.approx(0.4 + 0.1) and out[5:] == [0.0] * 3
    assert len(group.mix(controls(), 5)) == 5


@pytest.mark.parametrize("text, line, what", [
    ("R: 4x 10000 10000 10000 0\n\nR: 7x 1 1 1 0\n", 3, "geometry"),
    ("R: 4x 10000 10000\n", 1, "R:"),
    ("M: 1\nO: 10000 10000 0 -10000\n", 2, "O:"),
    ("M: 2\nO: 10000 10000 0 -10000 10000\nS: 0 0 10000 10000 0 -10000 10000\n", 3, "S:"),
    ("M: x\n", 1, "M:"),
])
def test_parse_errors_name_the_line(text: str, line: int, what: str) -> None:
    with pytest.raises(MixerParseError) as err:
        parse_mixer_text(text)
    assert err.value.line == line and what in str(err.value)


def test_error_line_counts_comment_lines() -> None:
    with pytest.raises(MixerParseError) as err:
        parse_mixer_text(QUAD_X_FILE.replace("4x", "4q"))
    assert err.value.line == 7


def test_filter_mixer_file() -> None:
    assert filter_mixer_file(SIMPLE_FILE) == (
        "M: 2\nO: 10000 10000 0 -10000 10000\nS: 0 0 10000 10000 0 -10000 10000\n"
        "S: 0 2 -5000 -8000 1000 -10000 10000\nZ:\n")


def test_incremental_buffer_rules() -> None:
    # a number cut at the buffer end: refused until more text arrives
    mixers, resid, refusal = load_from_buf("R: 4x 10000 100")
    assert mixers == [] and resid == 15 and "incomplete" in refusal.message
    mixers, resid, refusal = load_from_buf("R: 4x 10000 10000 10000 0\nM: 1\nO: 1")
    assert mixers == [] and refusal is not None  # the whole buffer's tail is checked
    mixers, resid, refusal = load_from_buf("R: 4x 10000 10000 10000 0\nM: 1\n")
    assert len(mixers) == 1 and resid == len("M: 1\n")
    mixers, resid, refusal = load_from_buf("xx Z: junk\n\0")
    assert len(mixers) == 1 and resid == 0


def test_chunked_upload_equals_whole() -> None:
    text = filter_mixer_file(QUAD_X_FILE + SIMPLE_FILE)
    chunks = encode_mixer_upload(text)
    assert all(len(c) <= 31 for c in chunks) and len(chunks) >= 2
    assert chunks[-1] == [0x6D74, 0x0A01]  # magic, append, "\n"
    upload = MixerUpload()
    results = [upload.handle(c) for c in chunks]
    assert results[-1].mixer_ok is True
    assert [type(m) for m in upload.group.mixers] == [MultirotorMixer, SimpleMixer, NullMixer]
    # a new upload starts from scratch
    for chunk in encode_mixer_upload("Z:\n"):
        upload.handle(chunk)
    assert [type(m) for m in upload.group.mixers] == [NullMixer]


def test_upload_ignores_bad_magic_and_short_payloads() -> None:
    upload = MixerUpload()
    assert upload.handle([0x1234, 0x0A00]).mixer_ok is None
    assert upload.handle([0x6D74]).mixer_ok is None


# -- issue 18, defect 10a: huge numbers are the C ints sscanf stores, never OverflowError ----

@pytest.mark.parametrize("digits, stored", [
    ("9" * 30, 1073741823),         # 10**30 - 1 modulo 2**32
    ("9" * 400, -1),                # 10**400 - 1 modulo 2**32, as a signed int
    ("2147483648", -2147483648),    # INT32_MAX + 1 wraps to INT32_MIN
])
def test_huge_scaler_numbers_are_read_as_the_c_int_the_io_stores(digits, stored) -> None:
    (mixer,) = parse_mixer_text(f"M: 0\nO: 10000 10000 0 -10000 {digits}\n")
    assert mixer.output_scaler.max_output == stored / 10000.0
    (quad,) = parse_mixer_text(f"R: 4x 10000 10000 10000 {digits}\n")
    assert quad.idle_speed == stored / 10000.0
    outputs = quad.mix(controls(1.0, -1.0, 1.0, 1.0), 8)
    assert all(math.isfinite(o) for o in outputs)


@pytest.mark.parametrize("name", sorted(p.name for p in (ROMFS_ROOT / "mixers").glob("*.main.mix")))
def test_every_romfs_main_mixer_uploads_to_the_e14_io(name: str) -> None:
    """What px4io does with a ROMFS main mixer: filter, 59-byte chunks, the IO's 256-byte
    buffer parsed only at a chunk ending on a space or line end. A file laid out so that no
    chunk does overflows the buffer and the IO never sets MIXER_OK (the AETR mixer's padded
    columns are there for that)."""
    text = filter_mixer_file((ROMFS_ROOT / "mixers" / name).read_text())
    io = MixerUpload()
    results = [io.handle(w) for w in encode_mixer_upload(text, 64)]
    assert results[-1].mixer_ok, io.last_error
    assert len(io.group) == len(parse_mixer_text(text))
