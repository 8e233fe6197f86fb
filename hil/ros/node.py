"""ROS-N: one flight-stack module run as a native ROS 1 node, unchanged.

The module gets the same platform objects as on the FMU (a :class:`~board.kernel.Kernel`, a
:class:`~firmware.platform.Platform`, :class:`~firmware.platform.params.Params`, a
:class:`~firmware.system.System` with the FMU's module table) and is started through the module
registry, as ``mc_att_control start`` on the FMU. Nothing in the module knows where it runs;
what differs is only where its inputs come from and where its outputs go:

- time: the kernel's virtual time is the ROS time (``use_sim_time`` and ``/clock``: the
  emulator's virtual time). A ``/clock`` message runs the kernel up to that time, so a work
  item (an interval, a delayed schedule, a queue busy with the previous item) runs when ROS time
  reaches it, and ``hrt_absolute_time()`` reads the ROS time in microseconds: the timestamps
  the FMU's messages carry, when ``/clock`` is the FMU's virtual time;
- inputs: every topic the module subscribes is subscribed on ROS as ``/fmu/out/<topic>``
  (instance n > 0: ``/fmu/out/<topic>_<n>``, see :func:`ros_topic`); a message is converted
  field by field (:mod:`hil.ros.msggen`) and published into the node's own uORB broker at the
  current ROS time, so the module's callback subscriptions schedule its work items as on the FMU;
- outputs: every topic the module advertises is published as ``/fmu/in/<topic>``, each message
  as it is published (queued topics lose none), with the same types.

rospy calls its callbacks on threads of its own; they only queue what they received
(:class:`RosNode`), and one thread takes the queue in order and runs the kernel, so the module's
code runs on one thread in virtual time order, as on the FMU. :class:`ModuleHost` is that
deterministic part without rospy (the unit tests drive it directly); :class:`RosNode` is the
edge (threads are allowed only in hil/).

A message the module cannot take (a value its uORB field cannot hold) is counted and dropped
with a throttled warning; ``/clock`` going backwards (a simulation restarted) is counted and
ignored. The module's log lines (PX4_INFO/WARN/ERR) go to rosout.
"""

from __future__ import annotations

import queue
import threading
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from typing import Any, Final

from board.kernel import Kernel, KernelError
from firmware.modules import system_params
from firmware.platform import SEV_ERR, SEV_INFO, SEV_WARN, Platform
from firmware.platform.module import FMU_V2_MODULES, ModuleBase, ModuleError, ModuleRegistry
from firmware.platform.msgdef import MessageRegistry, default_registry
from firmware.platform.params import ParamError, Params
from firmware.system import System

__all__ = ["IN_PREFIX", "OUT_PREFIX", "ModuleHost", "RosNode", "ros_topic"]

#: what the FMU (through the companion) publishes: the module's inputs
OUT_PREFIX: Final = "/fmu/out/"
#: what goes to the FMU: the module's outputs
IN_PREFIX: Final = "/fmu/in/"
#: messages received before the first /clock, kept for the module's start (beyond: dropped)
EARLY_MAX: Final = 256


def ros_topic(prefix: str, topic: str, instance: int = 0) -> str:
    """``/fmu/out/vehicle_attitude``; instance n > 0 gets ``_n`` (``/fmu/out/sensor_gyro_1``)."""
    return f"{prefix}{topic}" if instance == 0 else f"{prefix}{topic}_{instance}"


class ModuleHost:
    """One module on its own kernel, platform and parameters, driven from outside.

    ``advance(t_ns)`` runs the kernel to ``t_ns``; ``inject(topic, instance, msg)`` publishes
    a message into the broker at the current time and runs what it scheduled for now;
    ``output(topic, instance, msg)`` is called for every message the module publishes (not for
    those injected). Deterministic: no threads, no wall clock.
    """

    def __init__(self, module: str, args: Sequence[str] = (), *,
                 params: Mapping[str, object] | None = None, name: str | None = None,
                 output: Callable[[str, int, Any], None] | None = None,
                 log: Callable[[int, str, str], None] | None = None,
                 table: Mapping[str, str | type] | None = None,
                 registry: MessageRegistry | None = None) -> None:
        self.module_name = module
        self.args = list(args)
        self.name = name or module
        self.output = output
        self.log = log
        self.registry = registry or default_registry()
        self.kernel = Kernel(self.name)
        self.platform = Platform(self.kernel, self.registry)
        modules = ModuleRegistry(None, table if table is not None else FMU_V2_MODULES)
        cls = modules.load(module)      # ModuleError: no such module
        defs = {d.name: d for d in system_params.PARAMS}
        for d in cls.PARAMS:
            defs.setdefault(d.name, d)
        for d in modules.param_defs():  # what a module reads of its neighbours' (MPC_THR_HOVER)
            defs.setdefault(d.name, d)
        self.system = System(self.platform, None, modules=modules, console=self._console)
        self.system.params = Params(self.platform, defs.values())
        self.params = self.system.params
        for pname, value in (params or {}).items():
            if pname not in self.params:
                raise ParamError(f"{pname}: no such parameter")
            self.params.set(pname, value, notify=False)
        self.instance: ModuleBase | None = None
        self.inputs: set[tuple[str, int]] = set()
        self.outputs: set[tuple[str, int]] = set()
        self.counts: Counter[str] = Counter()
        self._injecting = False
        self._dmesg_seen: tuple[int, int, str, str] | None = None
        self._n_subs = self._n_pubs = -1

    # -- life cycle ------------------------------------------------------------------------------

    @property
    def started(self) -> bool:
        return self.instance is not None

    def start(self, t_ns: int) -> None:
        """Set the clock to ``t_ns`` (the first ROS time) and start the module there."""
        if self.started:
            raise ModuleError(f"{self.module_name}: already started")
        self.kernel.run(max(t_ns, self.kernel.now_ns))
        out: list[str] = []
        with self.system.redirect(out.append):
            rc = self.system.modules.start(self.module_name, self.args)
        text = "".join(out).strip()
        if rc != 0:
            raise ModuleError(text or f"{self.module_name}: start failed")
        if text:
            self._console(text + "\n")
        self.instance = self.system.modules.get(self.module_name)
        self._scan()
        self.kernel.run(self.kernel.now_ns)
        self._after()

    def stop(self) -> None:
        if self.started:
            self.system.modules.stop(self.module_name)
            self._after()
            self.instance = None

    # -- driving ---------------------------------------------------------------------------------

    def advance(self, t_ns: int) -> bool:
        """Run the module's work up to ROS time ``t_ns``; False (counted) if it is in the past."""
        if t_ns < self.kernel.now_ns:
            self.counts["clock_backwards"] += 1
            return False
        self.kernel.run(t_ns)
        self.counts["clock"] += 1
        self._after()
        return True

    def inject(self, topic: str, instance: int, msg: Any) -> None:
        """Publish ``msg`` on ``topic`` now (as a received message) and run what it triggers."""
        node = self.platform.orb.node(topic, instance)
        node.advertised = True
        self._injecting = True
        try:
            node.publish(msg)
        finally:
            self._injecting = False
        self.counts["in"] += 1
        self.kernel.run(self.kernel.now_ns)
        self._after()

    def time_us(self) -> int:
        return self.platform.time_us()

    # -- topics ----------------------------------------------------------------------------------

    def _scan(self) -> None:
        """Map the module's subscriptions and publications (again when their number changes)."""
        inst = self.instance
        if inst is None:
            return
        if len(inst.subscriptions) == self._n_subs and len(inst.publications) == self._n_pubs:
            return
        self._n_subs, self._n_pubs = len(inst.subscriptions), len(inst.publications)
        for sub in inst.subscriptions:
            self.inputs.add((sub.node.name, sub.node.instance))
        for pub in inst.publications:
            key = (pub.node.name, pub.node.instance)
            if key not in self.outputs:
                self.outputs.add(key)
                pub.node.callbacks.append(self._forwarder(pub.node.name, pub.node.instance))

    def _forwarder(self, topic: str, instance: int) -> Callable[[], None]:
        node = self.platform.orb.node(topic, instance)

        def forward() -> None:
            if self._injecting:
                return   # a message from ROS, not the module's
            self.counts["out"] += 1
            if self.output is not None:
                self.output(topic, instance, node.last)
        return forward

    def _after(self) -> None:
        self._scan()
        self._flush_log()

    # -- log and console -------------------------------------------------------------------------

    def _flush_log(self) -> None:
        dmesg = self.platform.dmesg
        if not dmesg or dmesg[-1] is self._dmesg_seen:
            return
        start = len(dmesg)
        while start > 0 and dmesg[start - 1] is not self._dmesg_seen:
            start -= 1
        self._dmesg_seen = dmesg[-1]
        if self.log is not None:
            for _t, sev, mod, text in dmesg[start:]:
                self.log(sev, mod, text)

    def _console(self, text: str) -> None:
        if self.log is not None:
            for line in text.splitlines():
                if line.strip():
                    self.log(SEV_INFO, self.name, line)

    def status_text(self) -> str:
        out: list[str] = []
        with self.system.redirect(out.append):
            self.system.modules.status(self.module_name)
        return "".join(out)


class RosNode:
    """The rospy edge of a :class:`ModuleHost`: ROS in, one thread runs the module, ROS out."""

    def __init__(self, host: ModuleHost, *, node_name: str | None = None,
                 init_node: bool = True, queue_size: int = 100) -> None:
        from hil.ros import msggen

        msggen.ros_python_path()
        import rosgraph
        import rospy

        uri = rosgraph.get_master_uri()
        if init_node and not rosgraph.is_master_online(uri):
            raise OSError(f"no ROS master at {uri} (start `roscore`, or set ROS_MASTER_URI)")
        self.rospy = rospy
        self.host = host
        self.msggen = msggen
        self.ros_mod = msggen.load()[1]
        self.node_name = node_name or host.name
        self.queue_size = queue_size
        if init_node:
            rospy.init_node(self.node_name, anonymous=False, disable_signals=True)
        self.sim_time = bool(rospy.get_param("/use_sim_time", False))
        self._q: queue.Queue[tuple[Any, ...]] = queue.Queue()
        self._subs: dict[tuple[str, int], Any] = {}
        self._pubs: dict[tuple[str, int], Any] = {}
        self._early: list[tuple[Any, ...]] = []
        self._stop = threading.Event()
        self.dropped: Counter[str] = Counter()
        self._warned: set[str] = set()
        #: the module's status (``NAME status``) when the node stopped
        self.final_status = ""
        host.output = self._publish
        host.log = self._log
        self._clock_sub = None
        if self.sim_time:
            from rosgraph_msgs.msg import Clock
            self._clock_sub = rospy.Subscriber("/clock", Clock, self._on_clock, queue_size=10)

    # -- rospy threads: only queue ---------------------------------------------------------------

    def _on_clock(self, msg: Any) -> None:
        self._q.put(("clock", msg.clock.to_nsec()))

    def _on_msg(self, topic: str, instance: int, msg: Any) -> None:
        self._q.put(("msg", topic, instance, msg))

    # -- the module's thread ---------------------------------------------------------------------

    def run(self, until: Callable[[], bool] | None = None) -> int:
        """Take the queue until ROS shuts down (or ``until()``); 0, or 1 if the module failed."""
        rospy = self.rospy
        wait_s = 0.1 if self.sim_time else 0.001
        try:
            while not rospy.is_shutdown() and not self._stop.is_set():
                if until is not None and until():
                    break
                if not self.sim_time:
                    self._handle(("clock", rospy.Time.now().to_nsec()))
                try:
                    item = self._q.get(timeout=wait_s)
                except queue.Empty:
                    continue
                self._handle(item)
                while True:   # drain what else arrived, in order
                    try:
                        item = self._q.get_nowait()
                    except queue.Empty:
                        break
                    self._handle(item)
        except (KernelError, ModuleError) as exc:
            rospy.logerr(f"{self.node_name}: {exc}")
            return 1
        finally:
            if self.host.started:
                self.final_status = self.host.status_text()
            self.host.stop()
        return 0

    def shutdown(self) -> None:
        self._stop.set()

    def _handle(self, item: tuple[Any, ...]) -> None:
        host = self.host
        if item[0] == "clock":
            t_ns = item[1]
            if not host.started:
                host.start(t_ns)
                self._connect()
                early, self._early = self._early, []
                for e in early:
                    self._handle(e)
            elif not host.advance(t_ns):
                self._warn_once("clock", f"/clock went back to {t_ns / 1e9:.3f} s (now "
                                f"{host.kernel.now_ns / 1e9:.3f} s): ignored")
            self._connect()
            return
        _kind, topic, instance, ros_msg = item
        if not host.started:
            if len(self._early) < EARLY_MAX:
                self._early.append(item)
            else:
                self.dropped["before_clock"] += 1
            return
        try:
            msg = self.msggen.converter(topic, host.registry, self.ros_mod).from_ros(ros_msg)
        except self.msggen.ConversionError as exc:
            self.dropped[topic] += 1
            self._warn_once(topic, f"{ros_topic(OUT_PREFIX, topic, instance)}: dropped: {exc}")
            return
        host.inject(topic, instance, msg)
        self._connect()

    def _connect(self) -> None:
        """A ROS subscriber per module input and a publisher per output (new ones only)."""
        rospy = self.rospy
        for topic, inst in sorted(self.host.inputs - self._subs.keys()):
            cls = self.msggen.converter(topic, self.host.registry, self.ros_mod).ros_cls
            self._subs[(topic, inst)] = rospy.Subscriber(
                ros_topic(OUT_PREFIX, topic, inst), cls, self._on_msg_cb(topic, inst),
                queue_size=self.queue_size, tcp_nodelay=True)
        for topic, inst in sorted(self.host.outputs - self._pubs.keys()):
            cls = self.msggen.converter(topic, self.host.registry, self.ros_mod).ros_cls
            self._pubs[(topic, inst)] = rospy.Publisher(
                ros_topic(IN_PREFIX, topic, inst), cls, queue_size=self.queue_size,
                tcp_nodelay=True)

    def _on_msg_cb(self, topic: str, instance: int) -> Callable[[Any], None]:
        def cb(msg: Any) -> None:
            self._on_msg(topic, instance, msg)
        return cb

    def _publish(self, topic: str, instance: int, msg: Any) -> None:
        pub = self._pubs.get((topic, instance))
        if pub is None:
            self._connect()
            pub = self._pubs.get((topic, instance))
            if pub is None:
                return
        pub.publish(self.msggen.converter(topic, self.host.registry, self.ros_mod).to_ros(msg))

    def _log(self, severity: int, module: str, text: str) -> None:
        rospy = self.rospy
        line = f"[{module}] {text}"
        if severity <= SEV_ERR:
            rospy.logerr(line)
        elif severity <= SEV_WARN:
            rospy.logwarn(line)
        elif severity <= SEV_INFO:
            rospy.loginfo(line)
        else:
            rospy.logdebug(line)

    def _warn_once(self, key: str, text: str) -> None:
        if key not in self._warned:
            self._warned.add(key)
            self.rospy.logwarn(f"{self.node_name}: {text} (further ones counted)")

    def topics(self) -> tuple[list[str], list[str]]:
        """(subscribed ROS topics, published ROS topics)."""
        return ([ros_topic(OUT_PREFIX, t, i) for t, i in sorted(self._subs)],
                [ros_topic(IN_PREFIX, t, i) for t, i in sorted(self._pubs)])
