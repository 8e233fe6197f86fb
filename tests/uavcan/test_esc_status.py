"""ESC status from CAN ESCs, in-process (UAVCAN_ENABLE 3, four ESC nodes, the commander
started by hand): ``esc_status`` from their esc.Status, a failing ESC's error count rising
(fault ``bus.can_esc_errors`` on the node model), and a silent ESC seen offline by the driver
and reported by the commander as PX4 does ("ESC3 offline", critical), then back online."""

from __future__ import annotations

import re
from types import SimpleNamespace

from fmu.board import FmuV2Board
from hil.faults import get_kind

MS = 1_000_000


def _rig(b):
    orch = SimpleNamespace(handles={"fmu": None}, t_ns=0,
                           call=lambda name, method, *args: b.call(method, *args))
    return SimpleNamespace(orch=orch, dev={})


def _fault(b, kind_name, target, params):
    kind = get_kind(kind_name)
    rig, p = _rig(b), kind.check(target, params)
    token = kind.start(rig, target, p, b.kernel.now_ns)
    return lambda: kind.stop(rig, target, p, b.kernel.now_ns, token)


def test_esc_status_error_count_and_a_lost_esc_reported(tmp_path):
    b = FmuV2Board(seed=1, fram_path=str(tmp_path / "fram.bin"), sd_root=str(tmp_path),
                   params={"SYS_AUTOSTART": 0, "UAVCAN_ENABLE": 3},
                   uavcan_nodes=("esc1@11", "esc2@12", "esc3@13", "esc4@14"))
    k = b.kernel
    k.run(500 * MS)
    assert b.ctl_shell("mixer load /dev/uavcan/esc /etc/mixers/quad_x.main.mix")[0] == 0
    assert b.ctl_shell("commander start")[0] == 0
    k.run(2_000 * MS)
    st = b.ctl_topic("esc_status")
    assert st["esc_count"] == 4 and st["esc_online_flags"] == 0b1111
    assert st["esc_connectiontype"] == 4  # ESC_CONNECTION_TYPE_CAN
    assert 13 <= st["_count"] <= 17        # 10 Hz from the first esc.Status on
    assert [e["esc_address"] for e in st["esc"]] == [11, 12, 13, 14, 0, 0, 0, 0]
    # 25 C at rest, through esc.Status's float16 kelvin
    assert all(e["esc_errorcount"] == 0 and abs(e["esc_temperature"] - 25.0) < 0.5
               for e in st["esc"][:4])
    # a failing ESC 2: 20 errors/s counted in its esc.Status, health WARNING
    stop = _fault(b, "bus.can_esc_errors", "fmu.12", {"errors_per_s": 20.0})
    k.run(3_000 * MS)
    errs = [e["esc_errorcount"] for e in b.ctl_topic("esc_status")["esc"][:4]]
    assert errs[0] == errs[2] == errs[3] == 0 and 16 <= errs[1] <= 20, errs
    k.run(3_500 * MS)  # the next 1 Hz NodeStatus carries the health
    _, out = b.ctl_shell("uavcan status")
    assert re.search(r"node 12: online, org.hil.esc sw 2.1, uptime \d+ s, health 1", out)
    assert re.search(r"node 11: online, org.hil.esc sw 2.1, uptime \d+ s, health 0", out)
    assert re.search(r"esc 1: node 12, .* errors 2\d, ", out)
    stop()
    k.run(4_000 * MS)
    kept = b.ctl_topic("esc_status")["esc"][1]["esc_errorcount"]
    assert kept >= 28
    k.run(4_500 * MS)
    assert b.ctl_topic("esc_status")["esc"][1]["esc_errorcount"] == kept  # healthy: count stays
    assert "health 1" not in b.ctl_shell("uavcan status")[1]
    # ESC 3 goes silent: offline 1.2 s after its last report, the commander says so once
    stop = _fault(b, "bus.can_node_silent", "fmu.13", {})
    t0 = k.now_ns
    k.run(t0 + 1_000 * MS)
    assert b.ctl_topic("esc_status")["esc_online_flags"] == 0b1111
    k.run(t0 + 1_500 * MS)
    assert b.ctl_topic("esc_status")["esc_online_flags"] == 0b1011
    k.run(t0 + 2_500 * MS)
    said = [(sev, text) for _, sev, mod, text in b.ctl_dmesg() if mod == "commander"
            and "ESC" in text]
    assert said == [(2, "ESC3 offline")]  # MAV_SEVERITY_CRITICAL, as mavlink_log_critical
    stop()
    k.run(k.now_ns + 500 * MS)
    assert b.ctl_topic("esc_status")["esc_online_flags"] == 0b1111
    said = [text for _, _, mod, text in b.ctl_dmesg() if mod == "commander" and "ESC" in text]
    assert said == ["ESC3 offline", "All ESCs online"]
