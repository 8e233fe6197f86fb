"""The px4_msgs package generated from firmware/msg (hil.ros.msggen): types, converters, cache.

Every uORB topic must reach ROS field for field and come back unchanged, through genpy's real
serialization; the package must be loadable by Debian's ROS tools in another process, and be
regenerated when a .msg file changes.
"""

from __future__ import annotations

import random
import shutil
import struct
import subprocess
from io import BytesIO
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from firmware.platform.msgdef import PRIMITIVES, MessageDef, MessageRegistry, default_registry
from hil.ros import msggen
from tests.fuzzing import fuzz

REG = default_registry()
MSG_DIR = Path(msggen.__file__).resolve().parents[2] / "firmware" / "msg"


@pytest.fixture(scope="module")
def ros_mod() -> Any:
    return msggen.load()[1]


def _f32(x: float) -> float:
    return float(struct.unpack("<f", struct.pack("<f", x))[0])


def _value(ptype: str, rng: random.Random) -> Any:
    if ptype == "bool":
        return rng.random() < 0.5
    if ptype == "float32":
        return _f32(rng.uniform(-1e4, 1e4))
    if ptype == "float64":
        return rng.uniform(-1e9, 1e9)
    lo, hi = msggen._INT_RANGE[ptype]
    return rng.choice([lo, hi, rng.randint(lo, hi)])


def random_uorb(mdef: MessageDef, rng: random.Random) -> Any:
    """A message of ``mdef`` with every field random (float32 fields exactly representable)."""
    assert mdef.cls is not None
    msg = mdef.cls()
    for f in mdef.fields:
        if f.type == "char":
            v: Any = "".join(rng.choice("abcXYZ 09_-") for _ in range(rng.randint(0, f.array or 1)))
        elif f.is_primitive:
            v = ([_value(f.type, rng) for _ in range(f.array)] if f.array
                 else _value(f.type, rng))
        else:
            sub = REG.messages[f.type]
            v = ([random_uorb(sub, rng) for _ in range(f.array)] if f.array
                 else random_uorb(sub, rng))
        setattr(msg, f.name, v)
    return msg


def _wire(ros_msg: Any) -> bytes:
    buf = BytesIO()
    ros_msg.serialize(buf)
    return buf.getvalue()


def _has_char(mdef: MessageDef) -> bool:
    return any(f.type == "char" or (not f.is_primitive and _has_char(REG.messages[f.type]))
               for f in mdef.fields)


def test_every_type_is_generated_field_for_field(ros_mod: Any) -> None:
    for name, mdef in REG.messages.items():
        cls = getattr(ros_mod, msggen.snake_to_camel(name))
        assert cls._type == msggen.ros_type(mdef)
        assert list(cls.__slots__) == [f.name for f in mdef.fields], name
        for f, slot_type in zip(mdef.fields, cls._slot_types):
            if f.type == "char":
                assert slot_type == "string"
            elif f.is_primitive:
                want = msggen.ROS_PRIMITIVE[f.type]
                assert slot_type == (f"{want}[{f.array}]" if f.array else want), (name, f.name)
            else:
                sub = f"{msggen.PACKAGE}/{msggen.snake_to_camel(f.type)}"
                assert slot_type == (f"{sub}[{f.array}]" if f.array else sub), (name, f.name)
        for cname, (_t, value) in mdef.constants.items():
            assert getattr(cls, cname) == value, (name, cname)


def test_every_topic_round_trips_through_ros_serialization(ros_mod: Any) -> None:
    rng = random.Random(24)
    assert len(REG.topics) > 50
    for topic, mdef in sorted(REG.topics.items()):
        conv = msggen.converter(topic, ros_module=ros_mod)
        for _ in range(3):
            msg = random_uorb(mdef, rng)
            ros_msg = conv.to_ros(msg)
            data = _wire(ros_msg)
            if not _has_char(mdef):
                # ROS 1 and uORB lay out a message the same way (LE, packed, fixed arrays):
                # an independent check of every field's type and order
                assert data == msg.pack(), topic
            back_ros = conv.ros_cls().deserialize(data)
            back = conv.from_ros(back_ros)
            assert back == msg, topic
            assert back.pack() == msg.pack(), topic


def test_a_nested_type_converts_its_members(ros_mod: Any) -> None:
    conv = msggen.converter("position_setpoint_triplet", ros_module=ros_mod)
    msg = REG.cls("position_setpoint_triplet")()
    msg.current.lat, msg.current.valid, msg.next.vx = 47.397742, True, 2.5
    r = conv.to_ros(msg)
    assert type(r.current).__name__ == "PositionSetpoint"
    assert (r.current.lat, r.current.valid, r.next.vx) == (47.397742, True, 2.5)
    assert conv.from_ros(r) == msg


def test_a_value_uorb_cannot_hold_is_refused_with_the_field_named(ros_mod: Any) -> None:
    conv = msggen.converter("vehicle_rates_setpoint", ros_module=ros_mod)
    good = conv.to_ros(REG.cls("vehicle_rates_setpoint")())
    bad = conv.to_ros(REG.cls("vehicle_rates_setpoint")())
    bad.thrust_body = [0.0, 0.0]
    with pytest.raises(msggen.ConversionError, match=r"thrust_body: expected 3 elements"):
        conv.from_ros(bad)
    bad = conv.to_ros(REG.cls("vehicle_rates_setpoint")())
    bad.timestamp = -1
    with pytest.raises(msggen.ConversionError, match=r"timestamp: -1 is outside uint64"):
        conv.from_ros(bad)
    bad.timestamp = "now"
    with pytest.raises(msggen.ConversionError, match=r"timestamp: 'now' is not an integer"):
        conv.from_ros(bad)
    assert conv.from_ros(good).timestamp == 0
    log = msggen.converter("log_message", ros_module=ros_mod)
    m = log.to_ros(REG.cls("log_message")())
    m.text = "x" * 128
    with pytest.raises(msggen.ConversionError, match=r"text of 128 characters, at most 127"):
        log.from_ros(m)
    m.text = "\u20ac"
    with pytest.raises(msggen.ConversionError, match="outside Latin-1"):
        log.from_ros(m)
    m.text = "x" * 127
    assert log.from_ros(m).text == "x" * 127


_SCALARS = st.one_of(st.integers(min_value=-(1 << 70), max_value=1 << 70), st.floats(),
                     st.booleans(), st.text(max_size=3), st.none(),
                     st.lists(st.integers(-5, 300), max_size=5), st.binary(max_size=5))


@fuzz(examples=300)
@given(topic=st.sampled_from(sorted(REG.topics)), data=st.data())
def test_fuzz_from_ros_converts_or_refuses(topic: str, data: st.DataObject) -> None:
    """Any value in any field of a ROS message: a uORB message that packs, or ConversionError."""
    conv = msggen.converter(topic, ros_module=msggen.load()[1])
    ros_msg = conv.to_ros(REG.topic(topic).cls())
    fields = REG.topic(topic).fields
    for _ in range(data.draw(st.integers(1, 3))):
        f = data.draw(st.sampled_from(fields))
        setattr(ros_msg, f.name, data.draw(_SCALARS))
    try:
        msg = conv.from_ros(ros_msg)
    except msggen.ConversionError:
        return
    assert len(msg.pack()) == REG.topic(topic).size


def _tmp_registry(msg_dir: Path) -> MessageRegistry:
    return MessageRegistry.from_dir(msg_dir)


def test_the_package_is_regenerated_when_a_msg_file_changes(tmp_path: Path) -> None:
    msgs = tmp_path / "msg"
    msgs.mkdir()
    for name in ("position_setpoint", "position_setpoint_triplet", "vehicle_rates_setpoint"):
        shutil.copy(MSG_DIR / f"{name}.msg", msgs)
    root = tmp_path / "cache"
    first = msggen.ensure_package(root, _tmp_registry(msgs))
    assert first.regenerated
    assert sorted(p.name for p in (first.package_dir / "msg").iterdir()) == [
        "PositionSetpoint.msg", "PositionSetpointTriplet.msg", "VehicleRatesSetpoint.msg"]
    again = msggen.ensure_package(root, _tmp_registry(msgs))
    assert not again.regenerated and again.digest == first.digest
    path = msgs / "vehicle_rates_setpoint.msg"
    path.write_text(path.read_text() + "float32 extra_field   # rad\n")
    changed = msggen.ensure_package(root, _tmp_registry(msgs))
    assert changed.regenerated and changed.digest != first.digest
    assert "float32 extra_field  # rad" in (changed.package_dir / "msg" /
                                            "VehicleRatesSetpoint.msg").read_text()
    assert "extra_field" in (changed.python_dir / "px4_msgs" / "msg" /
                             "_VehicleRatesSetpoint.py").read_text()
    assert not [p for p in root.iterdir() if p.name.startswith((".gen-", ".old-"))]


def test_rosmsg_in_another_process_loads_the_generated_types() -> None:
    """Debian's own tools (system Python) find and import px4_msgs with the documented env."""
    pkg = msggen.load()[0]
    env = {**__import__("os").environ, **pkg.env()}
    out = subprocess.run(["rosmsg", "show", "px4_msgs/PositionSetpointTriplet"], env=env,
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert "px4_msgs/PositionSetpoint current" in out.stdout
    assert "  float64 lat" in out.stdout
    code = ("import roslib.message as m; c = m.get_message_class('px4_msgs/VehicleAttitude'); "
            "print(c._md5sum)")
    out = subprocess.run(["/usr/bin/python3", "-c", code], env=env, capture_output=True,
                         text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == msggen.load()[1].VehicleAttitude._md5sum


def test_primitive_table_covers_every_px4_type() -> None:
    assert set(msggen.ROS_PRIMITIVE) == set(PRIMITIVES)
