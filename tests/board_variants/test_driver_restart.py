"""``DRIVER stop; DRIVER start`` from the shell, for an SPI driver (L3GD20) and an I2C driver
(HMC5883L): the driver's shell module owns its work item, perf counters and uORB
advertisements, so the restarted driver publishes on the same uORB instance, no stale instance
stays advertised, and there is one set of perf counters and one work item (docs/shell.md:
modules can be stopped and started again). A start that fails says why, directly, and leaves
nothing behind.
"""

from __future__ import annotations

import pytest

from fmu.board import FmuV2Board

BOOTED_NS = 1_500_000_000
MS = 1_000_000


@pytest.fixture(scope="module")
def board():
    b = FmuV2Board(seed=1, sd_root=None)  # rcS: rc.sensors starts the drivers from the spec
    b.kernel.run(BOOTED_NS)
    return b


def _snapshot(b, name, topic):
    """What the driver holds: its instance, advertised instances, perf counters, work items."""
    orb = b.platform.orb
    drv = b.system.modules.get(name).driver
    mine = [p.node for p in drv.own_pubs if p.node.name == topic]
    return {
        "instance": [n.instance for n in mine],
        "advertised": sorted(n.instance for n in orb.nodes() if n.name == topic and n.advertised),
        "perf": [pc.name for pc in b.platform.perf.counters if pc.name.startswith(name + ":")],
        "work_items": [i for q in b.platform.wq for i in q.items if i.name == name],
        "driver": drv,
    }


@pytest.mark.parametrize("name, topic", [("l3gd20", "sensor_gyro"), ("hmc5883", "sensor_mag")])
def test_stop_then_start_publishes_on_the_same_instance_with_one_set_of_resources(board, name,
                                                                                  topic):
    before = _snapshot(board, name, topic)
    assert len(before["instance"]) == 1 and len(before["work_items"]) == 1
    assert len(before["advertised"]) == 2  # two gyros / two compasses on the FMUv2
    (node,) = [n for n in board.platform.orb.nodes()
               if n.name == topic and n.instance == before["instance"][0]]

    assert board.ctl_shell(f"{name} stop") == (0, "")
    assert not node.advertised  # given back, not left with stale data
    assert not [pc for pc in board.platform.perf.counters if pc.name.startswith(name + ":")]
    assert not [i for q in board.platform.wq for i in q.items if i.name == name]
    count = node.publish_count
    board.kernel.run(board.kernel.now_ns + 50 * MS)
    assert node.publish_count == count  # nothing runs any more

    assert board.ctl_shell(f"{name} start") == (0, "")
    board.kernel.run(board.kernel.now_ns + 200 * MS)
    after = _snapshot(board, name, topic)
    assert after["driver"] is not before["driver"]
    assert after["instance"] == before["instance"]
    assert after["advertised"] == before["advertised"]
    assert after["perf"] == before["perf"]  # one set, the same names
    assert len(after["work_items"]) == 1 and after["work_items"][0] is after["driver"]
    assert node.advertised and node.publish_count > count + 5
    assert node.last.device_id == after["driver"].device_id if topic == "sensor_gyro" else True
    status, out = board.ctl_shell(f"{name} status")
    assert status == 0 and f"publishes {topic}[{before['instance'][0]}]" in out, out


def test_a_failed_start_says_why_and_leaves_nothing(board):
    """The HMC5883L answers with another ID: ``start`` prints the driver's own reason (not a
    line scraped from dmesg) and gives back what the driver took."""
    assert board.ctl_shell("hmc5883 stop")[0] == 0
    advertised = sorted(n.instance for n in board.platform.orb.nodes()
                        if n.name == "sensor_mag" and n.advertised)
    board.ctl_fault("hmc5883", "wrong_id", 0x414243)
    try:
        status, out = board.ctl_shell("hmc5883 start")
    finally:
        board.ctl_fault("hmc5883", "wrong_id", None)
    assert status == 1
    assert out == ("hmc5883: start failed: no instance started (wrong ID b'ABC' = 41 42 43 at "
                   "0x1E (expected b'H43' = 48 34 33))\n"), out
    assert not board.system.modules.is_running("hmc5883")
    assert not [pc for pc in board.platform.perf.counters if pc.name.startswith("hmc5883:")]
    assert not [i for q in board.platform.wq for i in q.items if i.name == "hmc5883"]
    assert sorted(n.instance for n in board.platform.orb.nodes()
                  if n.name == "sensor_mag" and n.advertised) == advertised
    assert board.ctl_shell("hmc5883 start") == (0, "")  # the right chip again


def test_the_gps_and_mtd_restart_with_one_set_of_counters_and_one_work_item(board):
    """The other two drivers of the spec: the GPS (a UART connector's device, advertising with
    its first fix) and the FRAM's MTD (no work item: its counters are what it holds)."""
    for name in ("gps", "mtd"):
        perf = [pc.name for pc in board.platform.perf.counters if pc.name.startswith(name + ":")
                or pc.name.startswith("fram:") and name == "mtd"]
        assert perf
        assert board.ctl_shell(f"{name} stop") == (0, ""), name
        assert board.ctl_shell(f"{name} start") == (0, ""), name
        again = [pc.name for pc in board.platform.perf.counters
                 if pc.name.startswith(name + ":") or pc.name.startswith("fram:") and name == "mtd"]
        assert sorted(again) == sorted(perf), name
    assert len([i for q in board.platform.wq for i in q.items if i.name == "gps"]) == 1
    assert board.ctl_shell("param get SDLOG_PROFILE")[0] == 0  # parameters still on the FRAM
