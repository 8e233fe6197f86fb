"""The fault catalogue as data: every kind is documented and checked, the package finds kind
modules by itself, and the Injector applies and undoes faults at virtual times."""

from __future__ import annotations

import sys
import textwrap

import pytest

from hil import faults
from hil.faults import CATALOGUE, LEVELS, LOAD_ERRORS, FaultError, Injector, get_kind
from hil.rc import RcRig, Transmitter

MS = 1_000_000


def test_every_module_of_the_package_loaded():
    assert LOAD_ERRORS == {}


def test_the_kinds_this_branch_registers_are_there_with_docs():
    want = {"sensor.absent", "sensor.stuck", "sensor.noise", "sensor.saturate",
            "sensor.drdy_stuck", "sensor.wrong_id", "sensor.bias_step", "rc.tx_off",
            "rc.out_of_range", "rc.sbus_failsafe", "rc.frame_loss", "rc.glitch",
            "gps.lost_fix", "gps.degraded", "gps.jamming", "gps.jump", "gps.absent",
            "board.crash", "board.fmu_hang", "board.fmu_reboot", "board.io_reset"}
    assert want <= set(CATALOGUE)
    for kind in CATALOGUE.values():
        assert kind.level in LEVELS
        assert len(kind.doc) > 80, kind.name       # says what happens in reality
    for name in want - {"board.fmu_hang"}:         # these name the chip/receiver/board they hit
        assert CATALOGUE[name].targets, name


def test_sensor_kinds_target_the_fmu_devices_by_their_spec_names():
    from board.specs import FMU_V2

    names = {d.name for b in FMU_V2.spi for d in b.devices} | \
            {d.name for b in FMU_V2.i2c for d in b.devices}
    for kind in CATALOGUE.values():
        if kind.level == "sensor":
            assert set(kind.targets) <= names, kind.name
    assert "ms5611" not in get_kind("sensor.drdy_stuck").targets  # it has no data-ready pin


def test_bad_names_targets_and_params_are_clear_errors():
    with pytest.raises(FaultError, match="unknown fault 'sensor_gone'.*sensor.absent"):
        get_kind("sensor_gone")
    with pytest.raises(FaultError, match="target 'bmi088' is not one of mpu6000"):
        get_kind("sensor.absent").check("bmi088", {})
    with pytest.raises(FaultError, match=r"unknown parameter\(s\) size.*known: factor"):
        get_kind("gps.degraded").check("gps", {"size": 3})
    assert get_kind("gps.jump").check("gps", {"east_m": 5.0}) == \
        {"north_m": 50.0, "east_m": 5.0, "down_m": 0.0}


def test_a_new_kind_module_joins_the_catalogue_without_any_list_to_edit(tmp_path):
    mod = tmp_path / "zz_extra_kinds.py"
    mod.write_text(textwrap.dedent('''
        from hil.faults import fault_kind

        @fault_kind("zz_test_kind", level="link", targets=("telem1",), doc="a test kind")
        def start(rig, target, params, t_ns):
            return None
    '''))
    faults.__path__.append(str(tmp_path))
    try:
        faults.load_kinds()
        assert CATALOGUE["zz_test_kind"].level == "link"
    finally:
        faults.__path__.remove(str(tmp_path))
        CATALOGUE.pop("zz_test_kind", None)
        sys.modules.pop("hil.faults.zz_extra_kinds", None)


def test_a_broken_kind_module_is_reported_not_fatal(tmp_path):
    (tmp_path / "zz_broken.py").write_text("raise RuntimeError('half-written module')\n")
    faults.__path__.append(str(tmp_path))
    try:
        faults.load_kinds()
        assert "half-written module" in LOAD_ERRORS["hil.faults.zz_broken"]
        assert "sensor.absent" in CATALOGUE
    finally:
        faults.__path__.remove(str(tmp_path))
        LOAD_ERRORS.pop("hil.faults.zz_broken", None)


class FakeOrch:
    """Records control calls; time moves by tick()."""

    def __init__(self) -> None:
        self.t_ns = 0
        self.quantum_ns = MS
        self.on_quantum: list = []
        self.calls: list[tuple] = []
        self.dead: dict = {}

    def call(self, board, method, *args):
        self.calls.append((self.t_ns, board, method, *args))

    def step_to(self, t_ns: int) -> None:
        while self.t_ns < t_ns:
            self.t_ns += self.quantum_ns
            for hook in self.on_quantum:
                hook(self)


def test_injector_applies_and_undoes_a_sensor_fault_at_virtual_times():
    orch = FakeOrch()
    inj = Injector(orch, {}).install()
    orch.step_to(100 * MS)
    af = inj.start("sensor.stuck", "l3gd20", duration_s=0.25)
    assert orch.calls == [(100 * MS, "fmu", "fault", "l3gd20", "frozen", True)]
    orch.step_to(340 * MS)
    assert af.active
    orch.step_to(400 * MS)
    assert not af.active and af.t_stop_ns == 350 * MS
    assert orch.calls[-1] == (350 * MS, "fmu", "fault", "l3gd20", "frozen", False)


def test_injector_defaults_the_target_and_refuses_durations_on_permanent_faults():
    orch = FakeOrch()
    inj = Injector(orch, {})
    af = inj.start("sensor.bias_step", params={"x": 0.1})
    assert af.target == "mpu6000"
    assert orch.calls[-1][-1] == (0.1, 0.0, 0.0)
    with pytest.raises(FaultError, match="cannot be undone"):
        inj.start("board.crash", "fmu", duration_s=1.0)


def test_rc_kinds_act_on_the_receivers_link_windows():
    orch = FakeOrch()
    rig = RcRig(Transmitter())
    rx = rig.add("dsm")
    inj = Injector(orch, {"rc": rig}).install()
    orch.step_to(500 * MS)
    inj.start("rc.out_of_range", "dsm", duration_s=0.2)
    assert rx.link_ok(499 * MS) and not rx.link_ok(600 * MS)
    orch.step_to(800 * MS)
    assert rx.link_ok(700 * MS) and not rx.link_ok(650 * MS)
    inj.start("rc.tx_off")
    assert not rig.tx.powered(orch.t_ns + 1)
    with pytest.raises(FaultError, match="no sbus receiver on this rig \\(fitted: dsm\\)"):
        inj.start("rc.sbus_failsafe")
    with pytest.raises(FaultError, match="prob 1.5 outside"):
        inj.start("rc.frame_loss", "dsm", {"prob": 1.5})
