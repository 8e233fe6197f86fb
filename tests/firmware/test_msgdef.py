"""Topic definitions: .msg parsing, derived classes and binary layouts."""

import struct

import pytest

from firmware.platform.msgdef import MessageRegistry, MsgError, default_registry, parse_msg


def _registry(tmp_path, files):
    for name, text in files.items():
        (tmp_path / f"{name}.msg").write_text(text)
    return MessageRegistry.from_dir(tmp_path)


def test_all_field_kinds_pack_and_unpack(tmp_path):
    reg = _registry(tmp_path, {
        "inner": "float32 a\nint16[2] b\n",
        "outer": (
            "uint64 timestamp\nbool flag\nchar[8] label\nuint8 u8\nint8 i8\nuint16 u16\n"
            "int32 i32\nint64 i64\nfloat64 f64\nfloat32[3] v\nInner one\ninner[2] two\n"
            "uint8 MODE_A = 3\nfloat32 GAIN = 0.5\nuint8 ORB_QUEUE_LENGTH = 4\n"
            "# TOPICS outer outer_copy\n"),
    })
    cls = reg.cls("outer")
    assert reg.cls("outer_copy") is cls
    assert reg.topic("outer").queue_length == 4
    assert cls.MODE_A == 3 and cls.GAIN == 0.5
    m = cls(timestamp=123, flag=True, label="hi", u8=255, i8=-5, u16=65535, i32=-7,
            i64=-(1 << 40), f64=1.25, v=[1.0, 2.0, 3.0])
    m.one.a = 0.5
    m.one.b = [1, -2]
    m.two[1].b = [7, 8]
    data = m.pack()
    expected_size = 8 + 1 + 8 + 1 + 1 + 2 + 4 + 8 + 8 + 12 + 3 * (4 + 4)
    assert len(data) == cls.SIZE == expected_size
    assert data[:8] == struct.pack("<Q", 123)
    back = cls.unpack(data)
    assert back == m
    assert back.label == "hi"
    assert back.two[1].b == [7, 8]
    assert reg.topic("outer").ulog_format().startswith(
        "outer:uint64_t timestamp;bool flag;char[8] label;uint8_t u8;")
    assert "inner one;inner[2] two;" in reg.topic("outer").ulog_format()


def test_copy_is_deep_for_arrays_and_nested(tmp_path):
    reg = _registry(tmp_path, {"inner": "float32 a\n", "outer": "float32[2] v\ninner n\n"})
    m = reg.cls("outer")(v=[1.0, 2.0])
    c = m.copy()
    m.v[0] = 9.0
    m.n.a = 3.0
    assert c.v == [1.0, 2.0] and c.n.a == 0.0


@pytest.mark.parametrize("text, message", [
    ("float32\n", "expected 'type name'"),
    ("float99 x\n", "unknown type"),
    ("uint8 x\nuint8 x\n", "duplicate field"),
    ("uint8 X = 300\n", "out of range"),
    ("uint8 X = abc\n", "bad uint8 constant"),
    ("float32[0] x\n", "positive"),
    ("uint8 ORB_QUEUE_LENGTH = 0\n", "ORB_QUEUE_LENGTH"),
])
def test_malformed_definitions_name_file_and_problem(tmp_path, text, message):
    with pytest.raises(MsgError, match=message):
        _registry(tmp_path, {"bad": text})


def test_error_names_the_line():
    with pytest.raises(MsgError, match=r"x\.msg:2"):
        parse_msg("uint8 a\nnonsense here too\n", "x", "x.msg")


def test_shipped_messages_parse():
    reg = default_registry()
    for topic in ("sensor_accel", "sensor_gyro", "sensor_baro", "vehicle_command", "input_rc"):
        cls = reg.cls(topic)
        assert cls().pack() and "timestamp" in cls._fields
    assert reg.topic("vehicle_command").queue_length == 8
