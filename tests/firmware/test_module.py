"""Modules: PX4's start/stop/status/custom command shape, lazy loading, resource release."""

import pytest

from firmware.modules.system_params import PARAMS
from firmware.platform.module import (
    FMU_V2_MODULES,
    ModuleBase,
    ModuleError,
    UsageError,
    WorkItemModule,
)
from firmware.platform.params import ParamDef, Params
from firmware.system import System


class Blinker(WorkItemModule):
    """A work item at 100 Hz that models 1 ms of CPU per run (10 % load) and publishes."""

    NAME = "blinker"
    DESCRIPTION = "test module publishing ping_test at 100 Hz"
    USAGE = ("hello             say hello",)
    WQ = "wq:lp_default"
    INTERVAL_US = 10_000
    CPU_COST_NS = 1_000_000
    PARAMS = (ParamDef("BLINK_RATE", "INT32", 100, group="Test"),)

    def _start(self):
        self.pub = self.advertise("ping_test")
        self.msg = self.platform.orb.new("ping_test")
        self.cycles = self.perf_alloc("count", "cycles")

    def run(self):
        self.msg.timestamp = self.platform.time_us()
        self.msg.seq += 1
        self.msg.value = 0.5 * self.msg.seq
        self.pub.publish(self.msg)
        self.cycles.count()

    def status_lines(self):
        return [f"seq {self.msg.seq}"]

    def custom_command(self, args):
        if args[0] == "hello":
            self.print("hello from blinker")
            return 0
        return super().custom_command(args)


class Idle(ModuleBase):
    """A module with options: ``idle start [-r RATE]``; rejects anything else."""

    NAME = "idle"
    USAGE = ("start [-r RATE]",)

    @classmethod
    def instantiate(cls, system, args):
        inst = cls(system, args)
        inst.rate = 10
        if args:
            if args[:1] != ["-r"] or len(args) != 2 or not args[1].isdigit():
                raise UsageError(f"bad options {' '.join(args)}")
            inst.rate = int(args[1])
        return inst


class Broken(ModuleBase):
    NAME = "broken"

    def _start(self):
        self.perf_alloc("count", "never freed?")
        raise RuntimeError("sensor did not answer")


def make_system(platform, tmp_path=None, table=None, **kw):
    params = Params(platform, list(PARAMS) + list(Blinker.PARAMS))
    modules = {"blinker": Blinker, "idle": Idle, "broken": Broken} if table is None else table
    return System(platform, params, modules=modules,
                  sd_root=tmp_path if tmp_path is not None else None, **kw)


@pytest.fixture
def system(platform):
    out = []
    s = make_system(platform, console=out.append)
    s.out = out
    return s


def test_start_status_stop_release_everything(system, platform):
    reg = system.modules
    assert reg.start("blinker") == 0
    assert reg.is_running("blinker") and reg.running() == ["blinker"]
    platform.kernel.run(100_000_000)  # 100 ms: 10 runs
    inst = reg.get("blinker")
    assert inst.work_item.run_count == 10
    assert platform.orb.node("ping_test").publish_count == 10
    assert reg.status("blinker") == 0
    text = "".join(system.out)
    assert "blinker: running" in text and "work item blinker on wq:lp_default: 10 runs" in text
    assert "blinker: cycles: 10 events" in text and "seq 10" in text
    assert reg.stop("blinker") == 0
    assert not reg.is_running("blinker")
    assert platform.perf.find("blinker: cycles") is None
    assert not platform.orb.exists("ping_test")
    assert all(i.name != "blinker" for i in platform.wq.get("wq:lp_default").items)
    platform.kernel.run(200_000_000)
    assert platform.orb.node("ping_test").publish_count == 10  # nothing runs after stop
    assert reg.start("blinker") == 0  # restartable


def test_errors_are_reported_not_raised(system):
    reg = system.modules
    assert reg.start("blinker") == 0
    assert reg.start("blinker") == 1
    assert reg.stop("idle") == 1
    assert reg.status("idle") == 1
    assert reg.start("broken") == 1
    assert not reg.is_running("broken")
    assert system.platform.perf.find("broken: never freed?") is None  # released on failure
    text = "".join(system.out)
    assert "blinker: already running" in text
    assert "idle: not running" in text
    assert "broken: start failed: RuntimeError: sensor did not answer" in text


def test_command_line_verbs_options_and_custom_commands(system):
    reg = system.modules
    assert reg.command("idle", ["start", "-r", "x"]) == 1
    assert reg.command("idle", ["-r", "50", "start"]) == 0  # options before the verb (PX4)
    assert reg.get("idle").rate == 50
    assert reg.command("blinker", ["hello"]) == 1          # not running
    assert reg.command("blinker", ["start"]) == 0
    assert reg.command("blinker", ["hello"]) == 0
    assert reg.command("blinker", ["frobnicate"]) == 1
    assert reg.command("blinker", []) == 1
    text = "".join(system.out)
    assert "idle: bad options -r x" in text and "Usage: idle <command>" in text
    assert "hello from blinker" in text
    assert "blinker: unrecognized command 'frobnicate'" in text and "  hello" in text
    assert "blinker: missing command" in text


def test_lazy_table_and_unavailable_modules(system):
    reg = system.modules
    reg.register("ghost", "firmware.modules.no_such_module:Ghost")
    reg.register("stub", "firmware.platform.module:NotThere")
    reg.register("notmod", "firmware.platform.params:ParamDef")
    for name in ("ghost", "stub", "notmod"):
        assert reg.command(name, ["start"]) == 1
    text = "".join(system.out)
    assert "ghost: not available in this build (no module firmware.modules.no_such_module)" in text
    assert "stub: not available in this build (firmware.platform.module has no NotThere)" in text
    assert "notmod: " in text and "is not a ModuleBase subclass" in text
    with pytest.raises(ModuleError):
        reg.register("bad", "no_colon")
    assert reg.command("ghost", ["status"], where="rcS:3: ") == 1
    assert "rcS:3: ghost: not running" in "".join(system.out)


def test_param_defs_are_collected_from_module_classes(system):
    reg = system.modules
    assert [d.name for d in reg.param_defs(["blinker", "ghost"])] == ["BLINK_RATE"]


def test_default_table_names_px4_commands(platform):
    s = System(platform)
    assert "mpu6000" in s.modules and "logger" in s.modules
    assert set(s.modules.names()) == set(FMU_V2_MODULES)
    assert all(":" in target for target in FMU_V2_MODULES.values())


def test_stop_all_in_reverse_order(system):
    reg = system.modules
    reg.start("blinker")
    reg.start("idle")
    reg.stop_all()
    assert reg.running() == []
