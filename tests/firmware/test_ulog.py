"""ULog writer: the bytes PX4 tools expect, checked against pyulog (an independent reader)."""

import io
import struct

import pytest

from firmware.modules.logger.ulog import SYNC_MAGIC, UlogError, UlogWriter, formats_for
from firmware.platform.msgdef import PRIMITIVES, MessageRegistry, default_registry, parse_msg

import pyulog  # noqa: E402 - a dependency of the package


def read(buf: io.BytesIO):
    return pyulog.ULog(io.BytesIO(buf.getvalue()))


def messages(data: bytes):
    """(type, payload) of every message after the 16-byte header."""
    out, pos = [], 16
    while pos < len(data):
        size, typ = struct.unpack_from("<HB", data, pos)
        out.append((chr(typ), data[pos + 3:pos + 3 + size]))
        pos += 3 + size
    assert pos == len(data)
    return out


def test_header_and_flag_bits_come_first():
    buf = io.BytesIO()
    UlogWriter(buf, 123456789)
    data = buf.getvalue()
    assert data[:7] == b"ULog\x01\x12\x35"
    assert data[7] == 1
    assert struct.unpack_from("<Q", data, 8)[0] == 123456789
    (typ, payload), = messages(data)
    assert typ == "B" and len(payload) == 40 and payload == bytes(40)
    u = read(buf)
    assert u.start_timestamp == 123456789 and not u.file_corruption


def test_every_topic_format_matches_its_msg_types():
    reg = default_registry()
    buf = io.BytesIO()
    w = UlogWriter(buf, 0)
    topics = sorted(reg.topics)
    for topic in topics:
        w.write_topic_formats(topic, reg.topic(topic), reg)
    ids = {topic: w.add_subscription(topic) for topic in topics}
    for topic in topics:
        w.write_data(ids[topic], reg.cls(topic)(timestamp=1000).pack())
    u = read(buf)
    assert not u.file_corruption
    assert sorted(d.name for d in u.data_list) == topics
    def flat(mdef, prefix=""):
        """(field, C type) as pyulog expands them: arrays indexed, nested types dotted."""
        out = []
        for f in mdef.fields:
            names = ([f"{prefix}{f.name}[{i}]" for i in range(f.array)] if f.array
                     else [f"{prefix}{f.name}"])
            for name in names:
                if f.type in PRIMITIVES:
                    out.append((name, PRIMITIVES[f.type][3]))
                else:
                    out += flat(reg.messages[f.type], name + ".")
        return out

    for d in u.data_list:
        expected = flat(reg.topic(d.name))
        assert [(x.field_name, x.type_str) for x in d.field_data] == expected, d.name
        assert list(d.data["timestamp"]) == [1000]


def test_values_and_multi_instances_read_back():
    reg = default_registry()
    buf = io.BytesIO()
    w = UlogWriter(buf, 0)
    w.write_topic_formats("sensor_gyro", reg.topic("sensor_gyro"), reg)
    a, b = w.add_subscription("sensor_gyro", 0), w.add_subscription("sensor_gyro", 1)
    cls = reg.cls("sensor_gyro")
    for i in range(5):
        w.write_data(a, cls(timestamp=1000 * i, x=0.5 * i, clip_counter=[1, 2, i]).pack())
        w.write_data(b, cls(timestamp=1000 * i + 1, device_id=7, z=-i).pack())
    u = read(buf)
    g0 = u.get_dataset("sensor_gyro", 0).data
    g1 = u.get_dataset("sensor_gyro", 1).data
    assert list(g0["timestamp"]) == [0, 1000, 2000, 3000, 4000]
    assert list(g0["x"]) == [0.0, 0.5, 1.0, 1.5, 2.0]
    assert list(g0["clip_counter[2]"]) == [0, 1, 2, 3, 4]
    assert list(g1["z"]) == [0, -1, -2, -3, -4] and set(g1["device_id"]) == {7}


def test_nested_types_are_defined_before_their_users():
    reg = MessageRegistry()
    reg.add(parse_msg("float32 x\nfloat32 y\nfloat32 z\n", "vec3"))
    reg.add(parse_msg("uint64 timestamp\nVec3 pos\nVec3[2] corners\nuint8 flag\n", "shape"))
    reg.build()
    fmts = formats_for("shape", reg.topic("shape"), reg)
    assert fmts == ["vec3:float x;float y;float z;",
                    "shape:uint64_t timestamp;vec3 pos;vec3[2] corners;uint8_t flag;"]
    buf = io.BytesIO()
    w = UlogWriter(buf, 0)
    w.write_topic_formats("shape", reg.topic("shape"), reg)
    mid = w.add_subscription("shape")
    cls = reg.cls("shape")
    msg = cls(timestamp=5)
    msg.pos.y = 2.0
    msg.corners[1].z = -3.0
    msg.flag = 9
    w.write_data(mid, msg.pack())
    d = read(buf).get_dataset("shape").data
    assert d["pos.y"][0] == 2.0 and d["corners[1].z"][0] == -3.0 and d["flag"][0] == 9


def test_logged_topic_needs_a_leading_timestamp():
    reg = MessageRegistry()
    reg.add(parse_msg("uint32 a\nuint64 timestamp\n", "bad"))
    reg.build()
    with pytest.raises(UlogError, match="must start with 'uint64 timestamp'"):
        formats_for("bad", reg.topic("bad"), reg)


def test_info_parameters_and_their_changes():
    buf = io.BytesIO()
    w = UlogWriter(buf, 0)
    w.write_info("sys_name", "PX4")
    w.write_info("ver_sw_release", 0x010B0200, "uint32_t")
    w.write_info("time_ref_utc", -3600)
    w.write_info("gain", 0.25)
    w.write_info_multiple("perf", "part one ", "char")
    w.write_info_multiple("perf", "part two", "char", is_continued=True)
    w.write_parameter("MC_ROLL_P", 6.5)
    w.write_parameter("SYS_AUTOSTART", 4001)
    w.write_parameter_default("MC_ROLL_P", 6.0, 1)
    w.write_logged_string(6, 100, "started")
    w.write_parameter("MC_ROLL_P", 7.0)
    u = read(buf)
    assert u.msg_info_dict == {"sys_name": "PX4", "ver_sw_release": 0x010B0200,
                               "time_ref_utc": -3600, "gain": 0.25}
    assert u.msg_info_multiple_dict["perf"] == [["part one ", "part two"]]
    assert u.initial_parameters == {"MC_ROLL_P": 6.5, "SYS_AUTOSTART": 4001}
    assert u.changed_parameters == [(0, "MC_ROLL_P", 7.0)]
    assert u.get_default_parameters(0) == {"MC_ROLL_P": 6.0}
    types = [p[1][1:].split(b" ")[0] for p in messages(buf.getvalue()) if p[0] == "P"]
    assert types == [b"float", b"int32_t", b"float"]


def test_definitions_after_the_data_section_are_refused():
    reg = default_registry()
    w = UlogWriter(io.BytesIO(), 0)
    w.write_topic_formats("ping_test", reg.topic("ping_test"), reg)
    w.add_subscription("ping_test")
    with pytest.raises(UlogError, match="definitions section"):
        w.write_topic_formats("sensor_baro", reg.topic("sensor_baro"), reg)
    with pytest.raises(UlogError, match="unknown msg_id"):
        w.write_data(9, b"")
    with pytest.raises(UlogError, match="before its format"):
        w.add_subscription("sensor_mag")


def test_logged_strings_sync_and_dropouts():
    reg = default_registry()
    buf = io.BytesIO()
    w = UlogWriter(buf, 0)
    w.write_topic_formats("ping_test", reg.topic("ping_test"), reg)
    mid = w.add_subscription("ping_test")
    w.write_logged_string(3, 1_000, "[sensors] no baro")
    w.write_tagged_string(4, 42, 2_000, "tagged")
    w.write_data(mid, reg.cls("ping_test")(timestamp=5_000).pack())
    w.write_sync()
    w.write_dropout(62)
    w.write_dropout(100_000)   # clamped to uint16
    with pytest.raises(UlogError, match="0..7"):
        w.write_logged_string(8, 0, "x")
    raw = buf.getvalue()
    assert [t for t, _ in messages(raw)] == list("BFALCDSOO")
    assert raw.count(SYNC_MAGIC) == 1
    u = read(buf)
    (m,) = u.logged_messages
    assert (m.log_level, m.log_level_str(), m.timestamp, m.message) == \
        (ord("3"), "ERROR", 1_000, "[sensors] no baro")
    (t,) = u.logged_messages_tagged[42]
    assert (t.log_level_str(), t.timestamp, t.message) == ("WARNING", 2_000, "tagged")
    assert [d.duration for d in u.dropouts] == [62, 0xFFFF]
    assert w.bytes_written == len(raw)
