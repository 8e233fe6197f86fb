"""The bridge's topic list: the ROMFS default loads, topic ids follow the .msg layout, and
every kind of bad file is refused with a clear reason."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from firmware.modules.uorb_bridge.topics import BridgeConfig, BridgeConfigError, topic_id
from firmware.platform.msgdef import MessageRegistry, default_registry, parse_msg
from tests.bridge.rig import ROMFS_TOPICS
from tests.fuzzing import fuzz

REG = default_registry()


def parse(text: str) -> BridgeConfig:
    return BridgeConfig.parse(text, REG, "t.yaml")


def test_default_list_loads_and_covers_the_attitude_controller():
    cfg = BridgeConfig.parse(ROMFS_TOPICS.read_text(), REG, "/etc/bridge/topics.yaml")
    out = {r.topic for r in cfg.sends("fmu")}
    # mc_att_control's inputs (McAttControlModule._start), parameter_update excepted: each
    # side has its own parameters
    assert {"vehicle_attitude", "vehicle_attitude_setpoint", "vehicle_control_mode",
            "vehicle_status", "vehicle_land_detected", "actuator_armed",
            "manual_control_setpoint", "hover_thrust_estimate"} <= out
    back = {r.topic: r.publish_as for r in cfg.receives("fmu")}
    assert back["vehicle_rates_setpoint"] == "companion_rates_setpoint"
    assert {"trajectory_setpoint", "offboard_control_mode", "vehicle_command"} <= set(back)
    assert cfg.receives("companion") == cfg.sends("fmu")
    att = next(r for r in cfg.sends("fmu") if r.topic == "vehicle_attitude")
    assert att.rate_hz == 0 and att.interval_us == 0 and att.size == REG.topic(att.topic).size


def test_topic_id_changes_with_name_and_layout():
    base = "uint64 timestamp\nfloat32 x\n"
    reg1 = MessageRegistry()
    reg1.add(parse_msg(base, "thing"))
    reg1.build()
    reg2 = MessageRegistry()
    reg2.add(parse_msg(base + "float32 y\n", "thing"))
    reg2.build()
    reg3 = MessageRegistry()
    reg3.add(parse_msg("uint64 timestamp\nint32 x\n", "thing"))
    reg3.build()
    ids = {topic_id("thing", r.topic("thing"), r) for r in (reg1, reg2, reg3)}
    assert len(ids) == 3
    assert topic_id("thing", reg1.topic("thing"), reg1) != \
        topic_id("other", reg1.topic("thing"), reg1)
    # deterministic: the same definition gives the same id on both sides
    assert topic_id("vehicle_attitude", REG.topic("vehicle_attitude"), REG) == \
        topic_id("vehicle_attitude", REG.topic("vehicle_attitude"), REG)


def test_nested_layout_is_part_of_the_id():
    outer = "uint64 timestamp\nInner a\n"
    regs = []
    for inner in ("float32 v\n", "float64 v\n"):
        r = MessageRegistry()
        r.add(parse_msg(inner, "inner"))
        r.add(parse_msg(outer, "outer"))
        r.build()
        regs.append(topic_id("outer", r.topic("outer"), r))
    assert regs[0] != regs[1]


@pytest.mark.parametrize("text, reason", [
    ("fmu_to_companion: [", "not valid YAML"),
    ("- 1\n- 2\n", "expected a mapping"),
    ("fmu_to_companion: []\nbogus: 1\n", "unknown key(s) bogus"),
    ("link_timeout_ms: 0\n", "link_timeout_ms must be"),
    ("heartbeat_hz: fast\n", "heartbeat_hz must be"),
    ("fmu_to_companion: {topic: x}\n", "must be a list"),
    ("fmu_to_companion: [vehicle_attitude]\n", "expected {topic: NAME"),
    ("fmu_to_companion: [{topic: no_such_topic}]\n", "unknown uORB topic 'no_such_topic'"),
    ("fmu_to_companion: [{topic: vehicle_attitude, rate: 5}]\n", "unknown key(s) rate"),
    ("fmu_to_companion: [{topic: vehicle_attitude, rate_hz: -1}]\n", "rate_hz must be"),
    ("fmu_to_companion: [{topic: vehicle_attitude, instance: 12}]\n", "instance must be"),
    ("fmu_to_companion: [{topic: vehicle_attitude, as: nope}]\n", "unknown uORB topic 'nope'"),
    ("fmu_to_companion: [{topic: vehicle_attitude, as: vehicle_status}]\n",
     "not the same message type"),
    ("fmu_to_companion: [{topic: vehicle_attitude}, {topic: vehicle_attitude}]\n",
     "listed twice"),
    ("fmu_to_companion: [{topic: vehicle_attitude}]\n"
     "companion_to_fmu: [{topic: vehicle_attitude}]\n", "would echo"),
])
def test_bad_files_refused_with_the_reason(text, reason):
    with pytest.raises(BridgeConfigError) as exc:
        parse(text)
    assert reason in str(exc.value) and str(exc.value).startswith("t.yaml")


def test_rename_both_ways_is_not_a_loop():
    cfg = parse("fmu_to_companion: [{topic: vehicle_rates_setpoint, as: "
                "companion_rates_setpoint}]\n"
                "companion_to_fmu: [{topic: vehicle_rates_setpoint, "
                "as: companion_rates_setpoint}]\n")
    assert len(cfg.sends("fmu")) == 1 and len(cfg.sends("companion")) == 1


def test_message_larger_than_a_frame_refused():
    reg = MessageRegistry()
    reg.add(parse_msg("uint64 timestamp\nuint8[2000] blob\n", "big"))
    reg.build()
    with pytest.raises(BridgeConfigError, match="packs to 2008 bytes, more than a frame"):
        BridgeConfig.parse("fmu_to_companion: [{topic: big}]\n", reg, "t.yaml")


def test_id_collision_refused(monkeypatch):
    from firmware.modules.uorb_bridge import topics

    monkeypatch.setattr(topics, "topic_id", lambda name, mdef, reg: 42)
    with pytest.raises(BridgeConfigError, match="have the same id 0x0000002a"):
        parse("fmu_to_companion: [{topic: vehicle_attitude}, {topic: vehicle_status}]\n")


@fuzz(examples=200)
@given(text=st.one_of(
    st.text(max_size=300),
    st.builds(lambda head, i, junk: head[:i] + junk + head[i:],
              st.just(ROMFS_TOPICS.read_text()), st.integers(0, 2000), st.text(max_size=20)),
))
def test_fuzz_config(text):
    """Any text: a loaded list or a BridgeConfigError naming the file, nothing else."""
    try:
        cfg = BridgeConfig.parse(text, REG, "f.yaml")
    except BridgeConfigError as exc:
        assert str(exc).startswith("f.yaml")
        return
    for r in cfg.fmu_to_companion + cfg.companion_to_fmu:
        assert r.topic in REG.topics and REG.topic(r.publish_as) is REG.topic(r.topic)
