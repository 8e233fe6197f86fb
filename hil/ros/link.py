"""The ROS 1 edge: a rospy node ``/fmu_hil`` on the companion board's "ros" port.

``hil fly --companion --ros`` puts this host device behind the world end of the wire
``companion.ros <-> world.ros`` (:func:`add_ros_link`, called by hil/system.py when
``SystemConfig.ros``). On the board side the ``ros_bridge`` module (firmware, deterministic)
turns the companion's uORB topics into records ``(topic, instance, packed bytes)`` and back; here
those records meet ROS:

* ``/clock`` (rosgraph_msgs/Clock): the virtual time, every :data:`CLOCK_PERIOD_NS` of it
  (250 Hz of virtual time), and ``/use_sim_time`` set true on the master, so a node started
  after ``hil fly`` runs on the emulator's time (rospy.Time.now(), timers, rosbag);
* ``/fmu/out/<topic>`` (``px4_msgs/<Type>``, generated from firmware/msg by hil/ros/msggen.py):
  every record the companion sends, field-exact;
* the standard views of hil/ros/views.py (``/fmu/imu/data``, ``/fmu/local_position/pose`` and
  ``odom``, ``/fmu/global_position/global``, ``/fmu/battery``) in mavros's frames;
* in: ``/fmu/in/<topic>`` for the ``in:`` topics of ros_topics.yaml (as PX4's ROS 2 offboard
  example publishes them), and ``/fmu/setpoint_position/local`` (mavros's) which becomes
  ``trajectory_setpoint`` + ``offboard_control_mode``.

Threads live here only (rospy's): subscriber callbacks convert and queue; the orchestrator's
thread drains the queue in ``run_until`` and puts the records on the wire at that virtual time,
so what ROS sends enters the lockstep between quanta, as a tool on any other port does (attached
tools make a run non-deterministic, by nature). A message from ROS that does not fit its uORB
type (hil.ros.msggen.ConversionError) or a non-finite setpoint is counted and dropped
(``stats()``), as is a record from the board that does not unpack.
"""

from __future__ import annotations

import struct
import sys
import threading
from collections import deque
from typing import Any, Callable, Final

from board.wiring import WORLD, Wire
from firmware.modules.ros_bridge.config import DEFAULT_PATH, RosTopics, parse_topics
from firmware.modules.ros_bridge.module import check_record
from firmware.modules.ros_bridge.port import PORT_NAME
from firmware.platform.msgdef import MessageRegistry, default_registry
from hil.ros import msggen

__all__ = ["CLOCK_PERIOD_NS", "NODE_NAME", "RosLink", "add_ros_link", "load_topics",
           "out_topic_name"]

#: /clock every 4 ms of virtual time: 250 Hz (a rospy.Rate or Timer finer than that steps)
CLOCK_PERIOD_NS: Final = 4_000_000
NODE_NAME: Final = "fmu_hil"
SETPOINT_TOPIC: Final = "/fmu/setpoint_position/local"
#: the uORB topics the standard views are made of (kept as they arrive)
VIEW_TOPICS: Final = frozenset({"vehicle_attitude", "sensor_combined", "vehicle_local_position",
                                "vehicle_global_position", "battery_status"})


def out_topic_name(topic: str, instance: int = 0) -> str:
    """``/fmu/out/<topic>``; instance n > 0 of a multi-instance topic ``/fmu/out/<topic>_n``."""
    return f"/fmu/out/{topic}" + (f"_{instance}" if instance else "")


def load_topics(registry: MessageRegistry | None = None) -> RosTopics:
    """The companion's list (ROMFS ``/etc/bridge/ros_topics.yaml``), as the edge reads it."""
    from firmware import romfs

    path = romfs.ROMFS_ROOT / DEFAULT_PATH[len("/etc/"):]
    return parse_topics(path.read_text(), registry or default_registry(), str(path))


class RosLink:
    """Host device owning the world end of the "ros" wire; a rospy node once :meth:`start`
    ed."""

    runs_ahead = False

    def __init__(self, topics: RosTopics, node_name: str = NODE_NAME,
                 clock_period_ns: int = CLOCK_PERIOD_NS,
                 registry: MessageRegistry | None = None,
                 log: Callable[[str], None] | None = None) -> None:
        self.topics = topics
        self.node_name = node_name
        self.clock_period_ns = clock_period_ns
        self.registry = registry or default_registry()
        self.log = log or (lambda text: print(text, file=sys.stderr, flush=True))
        self.ports = (PORT_NAME,)
        self._t_ns = 0
        self._next_clock_ns = 0
        self._out: list[Any] = []
        #: (topic, packed uORB message) from rospy's threads, drained by the orchestrator's
        self._rx: deque[tuple[str, bytes]] = deque(maxlen=10_000)
        self._latest: dict[str, Any] = {}
        self._sizes = {t: self.registry.topic(t).size
                       for t in {*(x.topic for x in topics.out), *topics.inbound_names()}}
        self._pubs: dict[tuple[str, int], Any] = {}
        self._views: dict[str, Any] = {}
        self._clock_pub: Any = None
        self._clock_cls: Any = None
        self._time_cls: Any = None
        from hil.ros import views  # rospy's message classes (no master needed)

        self._views_mod: Any = views
        self._subs: list[Any] = []
        self._lock = threading.Lock()
        self.started = False
        self.master_uri = ""
        self.counts: dict[str, int] = {"records_from_board": 0, "records_to_board": 0,
                                       "bad_records": 0, "ros_in": 0, "ros_dropped": 0,
                                       "clock": 0}

    # -- ROS side ---------------------------------------------------------------------------------

    def start(self) -> None:
        """Join the ROS graph at ``$ROS_MASTER_URI`` as ``/fmu_hil``; OSError if no master."""
        msggen.ros_python_path()
        import rosgraph
        import rospy
        from rosgraph_msgs.msg import Clock

        self.master_uri = uri = rosgraph.get_master_uri()
        if not rosgraph.is_master_online(uri):
            raise OSError(f"--ros: no ROS master at {uri} (start `roscore`, or set "
                          f"ROS_MASTER_URI)")
        msggen.load()  # px4_msgs generated (or up to date) and imported
        rospy.set_param("/use_sim_time", True)
        rospy.init_node(self.node_name, anonymous=False, disable_signals=True)
        self._clock_cls = Clock
        self._time_cls = rospy.Time
        self._clock_pub = rospy.Publisher("/clock", Clock, queue_size=10)
        for t in self.topics.out:
            cls = msggen.ros_class(t.topic, self.registry)
            self._pubs[(t.topic, t.instance)] = rospy.Publisher(
                out_topic_name(t.topic, t.instance), cls, queue_size=10)
        from geometry_msgs.msg import PoseStamped
        from nav_msgs.msg import Odometry
        from sensor_msgs.msg import BatteryState, Imu, NavSatFix

        for name, cls in (("/fmu/imu/data", Imu), ("/fmu/local_position/pose", PoseStamped),
                          ("/fmu/local_position/odom", Odometry),
                          ("/fmu/global_position/global", NavSatFix),
                          ("/fmu/battery", BatteryState)):
            self._views[name] = rospy.Publisher(name, cls, queue_size=10)
        for topic in sorted(self.topics.inbound_names()):
            cls = msggen.ros_class(topic, self.registry)
            self._subs.append(rospy.Subscriber(f"/fmu/in/{topic}", cls, self._on_in,
                                               callback_args=topic, queue_size=20))
        if "trajectory_setpoint" in self.topics.inbound_names() \
                and "offboard_control_mode" in self.topics.inbound_names():
            self._subs.append(rospy.Subscriber(SETPOINT_TOPIC, PoseStamped, self._on_setpoint,
                                               queue_size=20))
        self.started = True

    def _on_in(self, msg: Any, topic: str) -> None:
        """rospy thread: a /fmu/in/<topic> message, converted to uORB now (dropped and counted
        if it does not fit)."""
        try:
            uorb = msggen.converter(topic, self.registry).from_ros(msg)
        except (msggen.ConversionError, TypeError, ValueError) as exc:
            self._drop(f"/fmu/in/{topic}: {exc}")
            return
        data = self._pack(uorb, f"/fmu/in/{topic}")
        if data is not None:
            self._rx.append((topic, data))

    def _pack(self, uorb: Any, where: str) -> bytes | None:
        """rospy thread: an unstamped message (``timestamp`` 0, e.g. from ``rostopic pub``)
        stamped with the present virtual time, packed; None (dropped and counted) for a float
        beyond float32's range, which does not pack."""
        if getattr(uorb, "timestamp", 1) == 0:
            uorb.timestamp = self._t_ns // 1000
        try:
            return bytes(uorb.pack())
        except (struct.error, OverflowError) as exc:
            self._drop(f"{where}: {exc}")
            return None

    def _on_setpoint(self, msg: Any) -> None:
        """rospy thread: mavros's position setpoint (ENU) -> trajectory_setpoint and
        offboard_control_mode, stamped with the present virtual time."""
        try:
            sp, mode = self._views_mod.setpoint_from_pose(msg, 0, self.registry_new)
        except (ValueError, TypeError, AttributeError) as exc:
            self._drop(f"{SETPOINT_TOPIC}: {exc}")
            return
        sp_data = self._pack(sp, SETPOINT_TOPIC)
        mode_data = self._pack(mode, SETPOINT_TOPIC)
        if sp_data is not None and mode_data is not None:  # both or neither
            self._rx.append(("offboard_control_mode", mode_data))
            self._rx.append(("trajectory_setpoint", sp_data))

    def registry_new(self, topic: str, **fields: Any) -> Any:
        return self.registry.cls(topic)(**fields)

    def _drop(self, why: str) -> None:
        with self._lock:
            self.counts["ros_dropped"] += 1
            first = self.counts["ros_dropped"] == 1
        if first:  # once: a node that sends garbage at 50 Hz must not flood the terminal
            self.log(f"hil ros: dropped a message from ROS ({why}); further drops are counted")

    # -- host device --------------------------------------------------------------------------------

    def run_until(self, t_ns: int) -> None:
        self._t_ns = t_ns
        if self.started and t_ns >= self._next_clock_ns:
            c = self._clock_cls()
            c.clock = self._time_cls(t_ns // 1_000_000_000, t_ns % 1_000_000_000)
            self._clock_pub.publish(c)
            self.counts["clock"] += 1
            p = self.clock_period_ns
            self._next_clock_ns = (t_ns // p + 1) * p
        rx = self._rx
        while rx:
            topic, data = rx.popleft()
            self._out.append((PORT_NAME, t_ns, (topic, 0, data)))
            self.counts["records_to_board"] += 1
            self.counts["ros_in"] += 1

    def outputs(self, until_ns: int) -> list[Any]:
        out, self._out = self._out, []
        return out

    def input(self, port: str, t_ns: int, payload: Any) -> None:
        if port != PORT_NAME:
            raise ValueError(f"hil ros: no port {port!r}")
        checked = check_record(payload, self._sizes)
        if isinstance(checked, str):
            self.counts["bad_records"] += 1
            return
        topic, instance, data = checked
        self.counts["records_from_board"] += 1
        view = instance == 0 and topic in VIEW_TOPICS
        pub = self._pubs.get((topic, instance)) if self.started else None
        wanted = pub is not None and pub.get_num_connections() > 0
        if not (view or wanted):
            return  # nobody listens: not even unpacked
        msg = self.registry.cls(topic).unpack(data)  # type: ignore[attr-defined]
        if wanted and pub is not None:
            pub.publish(msggen.converter(topic, self.registry).to_ros(msg))
        if view:
            self._latest[topic] = msg
            if self.started:
                self._publish_views(topic)

    def _publish_views(self, topic: str) -> None:
        v = self._views_mod
        latest = self._latest
        att = latest.get("vehicle_attitude")
        if topic == "sensor_combined" and att is not None:
            self._view("/fmu/imu/data", lambda: v.imu(att, latest["sensor_combined"]))
        elif topic == "vehicle_local_position" and att is not None:
            lpos = latest[topic]
            self._view("/fmu/local_position/pose", lambda: v.pose(lpos, att))
            self._view("/fmu/local_position/odom",
                       lambda: v.odom(lpos, att, latest.get("sensor_combined")))
        elif topic == "vehicle_global_position":
            self._view("/fmu/global_position/global", lambda: v.navsat(latest[topic]))
        elif topic == "battery_status":
            self._view("/fmu/battery", lambda: v.battery(latest[topic]))

    def _view(self, name: str, make: Callable[[], Any]) -> None:
        pub = self._views[name]
        if pub.get_num_connections() > 0:
            pub.publish(make())

    def describe(self) -> str:
        """One line for ``hil fly``'s banner."""
        return (f"node /{self.node_name} on {self.master_uri}: /clock (use_sim_time), "
                f"/fmu/out/*, /fmu/in/*, /fmu/setpoint_position/local (docs/ros.md)")

    def stats(self) -> dict[str, int]:
        with self._lock:
            return dict(self.counts)

    def close(self) -> None:
        if self.started:
            import rospy

            for s in self._subs:
                s.unregister()
            for p in [*self._pubs.values(), *self._views.values(), self._clock_pub]:
                p.unregister()
            rospy.signal_shutdown("hil stopped")
            self.started = False


def add_ros_link(cfg: Any, hub: Any, devices: dict[str, Any]) -> list[Wire]:
    """The ROS edge on the companion's "ros" port (``SystemConfig.ros``, which brings the
    companion and its ``ros_bridge start``): the node joins the graph now (OSError naming the
    master if there is none) and the wires are returned."""
    link = RosLink(load_topics())
    link.start()
    hub.add(link)
    devices["ros"] = link
    about = "companion ros_bridge <-> the ROS 1 node /fmu_hil (hil/ros/link.py)"
    return [Wire(("companion", PORT_NAME), (WORLD, PORT_NAME), about),
            Wire((WORLD, PORT_NAME), ("companion", PORT_NAME), about)]
