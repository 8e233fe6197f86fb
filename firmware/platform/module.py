"""Modules in PX4's shape, and the board's table of them.

A module groups what it publishes, subscribes, its parameters, perf counters and work items,
so ``stop`` can release all of it and ``status`` can show it. Its command line is PX4's:
``NAME start [options]``, ``NAME stop``, ``NAME status`` and custom commands
(:meth:`ModuleBase.custom_command`).

The board's modules are listed by name in a table of ``"package.module:Class"`` strings and are
imported only when started (python-can's backend table), so a startup script can name a driver
that this tree does not have yet: starting it prints a clear error and the script goes on.

Module output goes through ``system.print``: the shell that runs a command redirects it to its
own console, as PX4 modules print to the stdout of the calling shell.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, ClassVar, Final

from mypy_extensions import mypyc_attr

from board.specs import FMU_V2, BoardSpecData
from firmware.platform.uorb import Publication, Subscription, SubscriptionCallback
from firmware.platform.workqueue import WorkItem

if TYPE_CHECKING:
    from firmware.platform.params import ParamDef
    from firmware.platform.perf import PerfCounter
    from firmware.system import System

__all__ = [
    "FMU_V2_MODULES",
    "STACK_MODULES",
    "board_modules",
    "ModuleBase",
    "ModuleError",
    "ModuleRegistry",
    "UsageError",
    "WorkItemModule",
]


@mypyc_attr(native_class=False)
class ModuleError(Exception):
    """A module could not be loaded, started or commanded; the message says why."""


@mypyc_attr(native_class=False)
class UsageError(ModuleError):
    """Bad arguments to a module command: the registry prints the message and the usage."""


@mypyc_attr(allow_interpreted_subclasses=True)
class ModuleBase:
    """Base of every module and driver started from the shell.

    Subclasses set ``NAME`` (the shell command), ``DESCRIPTION``, ``USAGE`` (option lines),
    ``PARAMS`` (their :class:`ParamDef` declarations) and override the hooks ``_start`` (PX4's
    ``init()``), ``_stop``, ``status_lines`` and ``custom_command``. Resources taken through
    :meth:`advertise`, :meth:`subscribe`, :meth:`subscribe_callback`, :meth:`perf_alloc` and
    :meth:`add_work_item` are released by :meth:`stop`, so a module can be restarted.
    """

    NAME: ClassVar[str] = ""
    DESCRIPTION: ClassVar[str] = ""
    USAGE: ClassVar[tuple[str, ...]] = ()
    PARAMS: ClassVar[tuple[ParamDef, ...]] = ()

    def __init__(self, system: System, args: Sequence[str] = ()) -> None:
        self.system = system
        self.platform = system.platform
        self.args = list(args)
        self.name = self.NAME or type(self).__name__.lower()
        self.publications: list[Publication] = []
        self.subscriptions: list[Subscription] = []
        self.perf_counters: list[PerfCounter] = []
        self.work_items: list[WorkItem] = []
        self.running = False

    @classmethod
    def instantiate(cls, system: System, args: Sequence[str]) -> ModuleBase:
        """Build the instance from the ``start`` options; raise :class:`UsageError` on bad ones."""
        return cls(system, args)

    # -- resources --------------------------------------------------------------------------------

    def advertise(self, topic: str, instance: int | None = 0) -> Publication:
        """Advertise ``topic`` (``instance=None``: the first free instance, for sensors)."""
        orb = self.platform.orb
        pub = orb.advertise_multi(topic) if instance is None else orb.advertise(topic, instance)
        self.publications.append(pub)
        return pub

    def subscribe(self, topic: str, instance: int = 0) -> Subscription:
        sub = Subscription(self.platform.orb, topic, instance)
        self.subscriptions.append(sub)
        return sub

    def subscribe_callback(self, item: WorkItem, topic: str, instance: int = 0,
                           interval_us: int = 0) -> SubscriptionCallback:
        """A subscription that schedules ``item`` on publication (registered now)."""
        sub = SubscriptionCallback(item, self.platform.orb, topic, instance, interval_us)
        sub.register_callback()
        self.subscriptions.append(sub)
        return sub

    def perf_alloc(self, kind: str, name: str) -> PerfCounter:
        """A perf counter named ``"<module>: <name>"`` (as PX4 names them), freed at stop."""
        pc = self.platform.perf.alloc(kind, f"{self.name}: {name}")
        self.perf_counters.append(pc)
        return pc

    def add_work_item(self, item: WorkItem) -> WorkItem:
        self.work_items.append(item)
        return item

    def param(self, name: str) -> Any:
        """A parameter's current value (the system's parameter set must declare it): an int or
        a float. Typed Any, not ``int | float``, which compiled code (hil.native) would turn
        into a float."""
        if self.system.params is None:
            raise ModuleError(f"{self.name}: no parameters on this system (wanted {name})")
        return self.system.params[name]

    def print(self, text: str = "") -> None:
        self.system.print(text)

    def info(self, text: str) -> None:
        self.platform.info(self.name, text)

    def warn(self, text: str) -> None:
        self.platform.warn(self.name, text)

    def error(self, text: str) -> None:
        self.platform.error(self.name, text)

    def emergency(self, text: str) -> None:
        self.platform.emergency(self.name, text)

    # -- life cycle -------------------------------------------------------------------------------

    def start(self) -> None:
        """Start (``_start`` may raise :class:`ModuleError`); resources are released on failure."""
        if self.running:
            raise ModuleError(f"{self.name}: already running")
        try:
            self._start()
        except BaseException:
            self._release()
            raise
        self.running = True

    def stop(self) -> None:
        if not self.running:
            return
        try:
            self._stop()
        finally:
            self._release()
            self.running = False

    def _release(self) -> None:
        for item in self.work_items:
            item.schedule_clear()
            if item in item.wq.items:
                item.wq.items.remove(item)
        for sub in self.subscriptions:
            if isinstance(sub, SubscriptionCallback):
                sub.unregister_callback()
        for pub in self.publications:
            pub.unadvertise()
        for pc in self.perf_counters:
            self.platform.perf.free(pc)
        self.work_items.clear()
        self.subscriptions.clear()
        self.publications.clear()
        self.perf_counters.clear()

    def _start(self) -> None:
        """Hook: take resources and schedule the first run."""

    def _stop(self) -> None:
        """Hook: anything beyond releasing the resources the base class tracks."""

    # -- status and commands ------------------------------------------------------------------------

    def status_lines(self) -> list[str]:
        """Hook: module-specific status lines (``NAME status``)."""
        return []

    def print_status(self) -> None:
        self.print(f"{self.name}: running")
        for item in self.work_items:
            self.print(f"  work item {item.name} on {item.wq.name}: {item.run_count} runs, "
                       f"{item.busy_ns_total / 1000:.0f} us busy")
        for pub in self.publications:
            node = pub.node
            self.print(f"  publishes {node.name}[{node.instance}]: {node.publish_count} msgs")
        for sub in self.subscriptions:
            self.print(f"  subscribes {sub.node.name}[{sub.node.instance}]")
        for pc in self.perf_counters:
            self.print(f"  {pc.summary()}")
        for line in self.status_lines():
            self.print(f"  {line}")

    def custom_command(self, args: list[str]) -> int:
        """Hook: a command other than start/stop/status, on the running instance."""
        self.print_usage(f"unrecognized command '{args[0]}'")
        return 1

    @classmethod
    def usage_lines(cls, name: str | None = None, reason: str = "") -> list[str]:
        name = name or cls.NAME or cls.__name__.lower()
        out = [f"{name}: {reason}"] if reason else []
        if cls.DESCRIPTION:
            out.append(f"### {name}: {cls.DESCRIPTION}")
        out.append(f"Usage: {name} <command> [arguments...]")
        out += ["  start", "  stop", "  status"]
        out += [f"  {line}" for line in cls.USAGE]
        return out

    def print_usage(self, reason: str = "") -> None:
        for line in self.usage_lines(self.name, reason):
            self.print(line)


class _ModuleWorkItem(WorkItem):
    """The work item of a :class:`WorkItemModule`: runs the module's ``run``."""

    def __init__(self, module: WorkItemModule) -> None:
        super().__init__(module.platform, module.name, module.WQ)
        self.cpu_cost_ns = module.CPU_COST_NS
        self.module = module
        # The dispatcher calls ``item.entry()``: the module's bound method saves a call layer
        # per run.
        self.entry = module.run

    def run(self) -> None:
        self.module.run()


@mypyc_attr(allow_interpreted_subclasses=True)
class WorkItemModule(ModuleBase):
    """A module that is one scheduled work item (PX4's ``ModuleBase + ScheduledWorkItem``).

    ``INTERVAL_US > 0`` runs it on an interval from start; otherwise ``_start`` (or a callback
    subscription made in it) schedules it.
    """

    WQ: ClassVar[str] = "wq:lp_default"
    INTERVAL_US: ClassVar[int] = 0
    CPU_COST_NS: ClassVar[int] = 0

    def __init__(self, system: System, args: Sequence[str] = ()) -> None:
        super().__init__(system, args)
        self.work_item: WorkItem | None = None

    def start(self) -> None:
        if not self.running and self.work_item is None:
            self.work_item = self.add_work_item(_ModuleWorkItem(self))
        super().start()
        if self.INTERVAL_US > 0 and self.work_item is not None:
            self.work_item.schedule_on_interval(self.INTERVAL_US)

    def _release(self) -> None:
        super()._release()
        self.work_item = None

    def run(self) -> None:  # pragma: no cover - abstract
        raise NotImplementedError(f"{type(self).__name__}.run")


#: The flight stack's modules and the drivers that are not a device of the board's spec (the
#: IO link, the PWM outputs, UAVCAN): shell name -> "package.module:Class". Entries whose
#: module does not exist yet are allowed: starting one prints "not available" and a script
#: goes on. The device drivers come from the board's spec (:func:`board_modules`).
STACK_MODULES: Final[dict[str, str]] = {
    "px4io": "firmware.drivers.px4io:Px4ioModule",
    "fmu": "firmware.drivers.px4fmu:FmuModule",
    "sensors": "firmware.modules.sensors:SensorsModule",
    "rc_update": "firmware.modules.rc_update:RcUpdateModule",
    "battery_status": "firmware.modules.battery:BatteryStatusModule",
    "dataman": "firmware.modules.dataman:DatamanModule",
    "commander": "firmware.modules.commander:CommanderModule",
    "logger": "firmware.modules.logger:LoggerModule",
    "mavlink": "firmware.modules.mavlink:MavlinkModule",
    "ekf2": "firmware.modules.ekf2:Ekf2Module",
    "mc_rate_control": "firmware.modules.mc_rate_control:McRateControlModule",
    "mc_att_control": "firmware.modules.mc_att_control:McAttControlModule",
    "mc_att_control_so3": "firmware.modules.mc_att_control_so3:McAttControlSo3Module",
    "mc_att_companion": "firmware.modules.mc_att_companion:McAttCompanionModule",
    "mc_att_select": "firmware.modules.mc_att_select:McAttSelectModule",
    "mc_pos_control": "firmware.modules.mc_pos_control:McPosControlModule",
    "fw_att_control": "firmware.modules.fw_att_control:FwAttControlModule",
    "fw_pos_control_l1": "firmware.modules.fw_pos_control_l1:FwPosControlL1Module",
    "navigator": "firmware.modules.navigator:NavigatorModule",
    "vtol_att_control": "firmware.modules.vtol_att_control:VtolAttControlModule",
    "land_detector": "firmware.modules.land_detector:LandDetectorModule",
    "uavcan": "firmware.drivers.uavcan:UavcanModule",
    "failure_injector": "firmware.modules.failure_injector:FailureInjectorModule",
    "load_mon": "firmware.modules.load_mon:LoadMonModule",
    "uorb_bridge": "firmware.modules.uorb_bridge:UorbBridgeModule",
}


def board_modules(spec: BoardSpecData) -> dict[str, str]:
    """The module table of a board: the driver of every device in its spec (a board variant
    with one more device registers that device's driver, one without a device does not
    register its driver), then the flight stack's modules."""
    table = spec.driver_modules()
    for name, target in STACK_MODULES.items():
        table.setdefault(name, target)
    return table


#: The FMUv2 board's module table (its spec's drivers and the stack's modules).
FMU_V2_MODULES: Final[dict[str, str]] = board_modules(FMU_V2)


class ModuleRegistry:
    """The board's modules by name: lazy import, start/stop/status and the command line."""

    def __init__(self, system: System | None, table: Mapping[str, str | type] | None = None
                 ) -> None:
        self.system = system
        self._table: dict[str, str | type] = dict(table if table is not None else FMU_V2_MODULES)
        self._instances: dict[str, ModuleBase] = {}
        self._where = ""

    # -- the table --------------------------------------------------------------------------------

    def register(self, name: str, target: str | type) -> None:
        """Add or replace a module: a ``"package.module:Class"`` string or the class itself."""
        if isinstance(target, str) and ":" not in target:
            raise ModuleError(f"module {name}: target {target!r} is not 'package.module:Class'")
        self._table[name] = target

    def names(self) -> list[str]:
        return sorted(self._table)

    def __contains__(self, name: object) -> bool:
        return name in self._table

    def load(self, name: str) -> type[ModuleBase]:
        """The module's class, imported now; :class:`ModuleError` says why it is unavailable."""
        try:
            target = self._table[name]
        except KeyError:
            raise ModuleError(f"{name}: no such module") from None
        if isinstance(target, str):
            mod_name, _, cls_name = target.partition(":")
            try:
                module = importlib.import_module(mod_name)
            except ModuleNotFoundError as exc:
                why = (f"no module {mod_name}" if exc.name and mod_name.startswith(exc.name)
                       else f"{mod_name}: {exc}")
                raise ModuleError(f"{name}: not available in this build ({why})") from None
            except ImportError as exc2:
                raise ModuleError(f"{name}: not available in this build "
                                  f"({mod_name}: {exc2})") from None
            cls = getattr(module, cls_name, None)
            if cls is None:
                raise ModuleError(f"{name}: not available in this build "
                                  f"({mod_name} has no {cls_name})")
        else:
            cls = target
        if not (isinstance(cls, type) and issubclass(cls, ModuleBase)):
            raise ModuleError(f"{name}: {target!r} is not a ModuleBase subclass")
        return cls

    def param_defs(self, names: Sequence[str] | None = None) -> list[ParamDef]:
        """The PARAMS of the named (default: all available) modules; imports them."""
        out: list[ParamDef] = []
        for name in names if names is not None else self.names():
            try:
                out.extend(self.load(name).PARAMS)
            except ModuleError:
                continue
        return out

    # -- instances --------------------------------------------------------------------------------

    def is_running(self, name: str) -> bool:
        inst = self._instances.get(name)
        return inst is not None and inst.running

    def get(self, name: str) -> ModuleBase | None:
        inst = self._instances.get(name)
        return inst if inst is not None and inst.running else None

    def running(self) -> list[str]:
        return sorted(n for n in self._instances if self.is_running(n))

    def _print(self, text: str) -> None:
        if self.system is not None:
            self.system.print(text)

    def _err(self, text: str) -> None:
        """An error line, prefixed with the script location of the command being run."""
        self._print(f"{self._where}{text}")

    def start(self, name: str, args: Sequence[str] = ()) -> int:
        if self.system is None:
            raise ModuleError("module registry has no system")
        if self.is_running(name):
            inst = self._instances[name]
            if getattr(inst, "MULTI_INSTANCE", False):  # mavlink: one more link
                try:
                    return int(inst.start_instance(list(args)))  # type: ignore[attr-defined]
                except UsageError as exc:
                    self._err(f"{name}: {exc}")
                    return 1
            self._err(f"{name}: already running")
            return 1
        try:
            cls = self.load(name)
            inst = cls.instantiate(self.system, list(args))
            inst.name = name
            inst.start()
        except UsageError as exc:
            self._err(f"{name}: {exc}")
            for line in self._usage(name):
                self._print(line)
            return 1
        except ModuleError as exc2:
            msg = str(exc2)
            self._err(msg if msg.startswith(f"{name}:") else f"{name}: start failed: {msg}")
            return 1
        except Exception as exc3:  # noqa: BLE001 - a module bug must not take the shell down
            self._err(f"{name}: start failed: {type(exc3).__name__}: {exc3}")
            return 1
        self._instances[name] = inst
        if self.system.profiler is not None:
            self.system.profiler.attach(self.system.platform)
        return 0

    def stop(self, name: str) -> int:
        inst = self.get(name)
        if inst is None:
            self._err(f"{name}: not running")
            return 1
        try:
            inst.stop()
        except Exception as exc:  # noqa: BLE001 - a module bug must not take the shell down
            self._err(f"{name}: stop failed: {type(exc).__name__}: {exc}")
            return 1
        finally:
            self._instances.pop(name, None)
        return 0

    def stop_all(self) -> None:
        for name in reversed(self.running()):
            self.stop(name)

    def status(self, name: str) -> int:
        inst = self.get(name)
        if inst is None:
            self._err(f"{name}: not running")
            return 1
        inst.print_status()
        return 0

    def _usage(self, name: str) -> list[str]:
        try:
            return self.load(name).usage_lines(name)
        except ModuleError:
            return ModuleBase.usage_lines(name)

    def command(self, name: str, args: Sequence[str], where: str = "") -> int:
        """``NAME [options] start|stop|status|<custom> [...]``: options before the verb go to
        ``start`` (PX4 drivers take ``hmc5883 -X start``). ``where`` prefixes error lines (the
        shell passes ``FILE:LINE: `` inside scripts)."""
        saved, self._where = self._where, where
        try:
            return self._command(name, list(args))
        finally:
            self._where = saved

    def _command(self, name: str, args: list[str]) -> int:
        verb_at = next((i for i, a in enumerate(args) if a in ("start", "stop", "status")),
                       None)
        if verb_at is None:  # a custom command: the first word that is not an option
            verb_at = next((i for i, a in enumerate(args) if not a.startswith("-")), None)
        if verb_at is None:
            self._err(f"{name}: missing command" + (f" after {' '.join(args)}" if args else ""))
            for line in self._usage(name):
                self._print(line)
            return 1
        verb = args[verb_at]
        rest = args[:verb_at] + args[verb_at + 1:]
        if verb == "start":
            return self.start(name, rest)
        if verb == "stop":
            return self.stop(name)
        if verb == "status":
            return self.status(name)
        if verb in ("help", "usage"):
            for line in self._usage(name):
                self._print(line)
            return 0
        inst = self.get(name)
        if inst is None:
            try:
                self.load(name)
            except ModuleError as exc3:
                self._err(str(exc3))
                return 1
            self._err(f"{name}: not running")
            return 1
        try:
            return int(inst.custom_command([verb] + rest))
        except UsageError as exc:
            self._err(f"{name}: {exc}")
            inst.print_usage()
            return 1
        except Exception as exc2:  # noqa: BLE001 - a module bug must not take the shell down
            self._err(f"{name} {verb}: failed: {type(exc2).__name__}: {exc2}")
            return 1

    def instances(self) -> dict[str, Any]:
        return {n: self._instances[n] for n in self.running()}
