"""ros_bridge (companion firmware) on a bare board: topics out at their rates, records in to the
broker, bad records dropped and counted by cause, and the topic list refused when malformed."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from board.board import Board
from firmware.modules.ros_bridge.config import ConfigError, parse_topics
from firmware.modules.ros_bridge.module import DROP_CAUSES, RosBridgeModule, check_record
from firmware.modules.ros_bridge.port import INBOX_MAX, expose_ros_port
from firmware.platform import Platform
from firmware.platform.module import ModuleRegistry
from firmware.platform.msgdef import default_registry
from firmware.platform.uorb import Subscription
from firmware.system import System
from tests.fuzzing import fuzz

TOPICS = """
out:
  - {topic: vehicle_attitude, rate_hz: 50}
  - {topic: battery_status}
in:
  - {topic: trajectory_setpoint}
  - {topic: vehicle_command}
"""


class RosBoard(Board):
    """A bare board with the ros port, as the companion has it."""

    adc = None

    def __init__(self) -> None:
        super().__init__("ros_test")
        self.ros_port = expose_ros_port(self)
        self.platform = Platform(self.kernel)
        self.system = System(self.platform, hw=self,  # type: ignore[arg-type]
                             modules=ModuleRegistry(None, {"ros_bridge": RosBridgeModule}))
        self.system.modules.system = self.system


@pytest.fixture
def rig(tmp_path):
    (tmp_path / "t.yaml").write_text(TOPICS)
    b = RosBoard()
    b.system.sd_root = tmp_path
    assert b.system.modules.start("ros_bridge", ["-c", "t.yaml"]) == 0
    mod = b.system.modules.get("ros_bridge")
    assert isinstance(mod, RosBridgeModule)
    return b, mod


def test_out_at_rate_and_in_published(rig):
    b, mod = rig
    orb = b.platform.orb
    att = orb.advertise("vehicle_attitude")
    m = orb.new("vehicle_attitude")
    # 250 Hz attitude for 1 s: 50 Hz out (the first one at once), each record packed bytes
    for i in range(250):
        t_ns = i * 4_000_000
        b.kernel.run(t_ns)
        m.timestamp = t_ns // 1000
        m.q = [1.0, 0.0, 0.0, float(i)]
        att.publish(m)
    out = b.advance(1_000_000_000, [])
    recs = [p for port, _t, p in out if port == "ros"]
    assert 49 <= len(recs) <= 51, len(recs)
    assert {r[0] for r in recs} == {"vehicle_attitude"}
    first = orb.registry.cls("vehicle_attitude").unpack(recs[0][2])
    assert first.q == [1.0, 0.0, 0.0, 0.0] and recs[0][1] == 0
    # in: a command arrives as a record and is published on the broker, field-exact
    sub = Subscription(orb, "vehicle_command")
    cmd = orb.new("vehicle_command", command=400, param1=1.0, target_system=1, timestamp=7)
    b.advance(1_010_000_000, [("ros", 1_005_000_000, ("vehicle_command", 0, cmd.pack()))])
    got = sub.update()
    assert got == cmd and mod.received["vehicle_command"] == 1


def test_bad_records_counted_and_dropped(rig):
    b, mod = rig
    orb = b.platform.orb
    good = orb.new("trajectory_setpoint", yaw=1.0).pack()
    bad = [("no_such_topic", 0, good), ("vehicle_attitude", 0, good),  # not an `in` topic
           ("trajectory_setpoint", 0, good[:-1]), ("trajectory_setpoint", 9, good),
           ("trajectory_setpoint", True, good), "junk", ("trajectory_setpoint", 0),
           (1, 2, 3), None]
    b.advance(10_000_000, [("ros", 1_000_000, r) for r in bad])
    assert mod.dropped == {"malformed": 5, "unknown_topic": 2, "bad_instance": 1,
                           "wrong_size": 1}
    assert not orb.exists("trajectory_setpoint")
    lines: list[str] = []
    with b.system.redirect(lines.append):
        b.system.modules.command("ros_bridge", ["status"])
    assert "dropped: malformed 5, unknown_topic 2, bad_instance 1, wrong_size 1" in "".join(lines)


def test_inbox_bounded():
    b = RosBoard()  # no module listening: records wait, the oldest dropped beyond the bound
    for i in range(INBOX_MAX + 5):
        b.ros_port.deliver(i, ("x", 0, b""))
    assert len(b.ros_port.inbox) == INBOX_MAX and b.ros_port.overflow == 5


@pytest.mark.parametrize("text, why", [
    ("out: [{topic: nope}]", "no uORB topic 'nope'"),
    ("out: [{topic: vehicle_attitude, rate_hz: -1}]", "rate_hz"),
    ("in: [{topic: vehicle_command, rate_hz: 5}]", "unknown key(s) rate_hz"),
    ("out: [{topic: battery_status}, {topic: battery_status}]", "listed twice"),
    ("[1, 2]", "expected a mapping"),
    ("out: {topic: x}", "'out' must be a list"),
    ("out: [{topic: battery_status, instance: 7}]", "instance"),
    ("topics: []", "unknown key(s) topics"),
    ("out: [", "not YAML"),
])
def test_topic_list_refused(text, why):
    with pytest.raises(ConfigError, match=None) as exc:
        parse_topics(text, default_registry(), "t.yaml")
    assert why in str(exc.value) and "t.yaml" in str(exc.value)


def test_romfs_list_loads():
    from firmware import romfs

    text = (romfs.ROMFS_ROOT / "bridge" / "ros_topics.yaml").read_text()
    topics = parse_topics(text, default_registry())
    assert {"trajectory_setpoint", "offboard_control_mode", "vehicle_command"} \
        <= topics.inbound_names()
    assert "vehicle_attitude" in {t.topic for t in topics.out}


_SIZES = {"trajectory_setpoint": default_registry().topic("trajectory_setpoint").size}
_GOOD = ("trajectory_setpoint", 0, bytes(_SIZES["trajectory_setpoint"]))


@fuzz(300)
@given(st.one_of(
    st.tuples(st.sampled_from(["trajectory_setpoint", "vehicle_command", "", "x" * 300]),
              st.integers(-5, 10) | st.booleans(), st.binary(max_size=120)),
    st.tuples(st.sampled_from(["trajectory_setpoint"]), st.just(0),
              st.binary(min_size=len(_GOOD[2]), max_size=len(_GOOD[2]))),
    st.lists(st.integers() | st.text(max_size=5) | st.binary(max_size=5) | st.none(),
             max_size=5),
    st.none() | st.integers() | st.floats() | st.text(max_size=10)))
def test_fuzz_record_check(record):
    """Any payload a ROS edge could put on the port is accepted as a record of an `in` topic of
    the right size (then it unpacks) or refused with one of the causes; never an exception."""
    got = check_record(record, _SIZES)
    if isinstance(got, str):
        assert got in DROP_CAUSES
    else:
        topic, _inst, payload = got
        default_registry().cls(topic).unpack(payload)  # type: ignore[attr-defined]


@fuzz(200)
@given(st.one_of(
    st.text(max_size=200),
    st.builds(lambda i, j, junk: TOPICS[:i] + junk + TOPICS[j:],
              st.integers(0, len(TOPICS)), st.integers(0, len(TOPICS)),
              st.sampled_from(["", ":", "[", "{", "- ", "\n  - {topic: ", "rate_hz: -", "!!python",
                               "*a", "&a ", "\t", "instance: 99", "topic: [1]", "'x'"]))))
def test_fuzz_topic_list(text):
    """A topic list file (ROMFS or `-c FILE`) loads or is refused with ConfigError, nothing
    else; what loads names only known topics."""
    try:
        topics = parse_topics(text, default_registry(), "t.yaml")
    except ConfigError:
        return
    for t in (*topics.out, *topics.inbound):
        default_registry().topic(t.topic)
        assert t.rate_hz >= 0 and 0 <= t.instance <= 3
