"""The FMU's side of the bridge as the board starts it: rcS starts uorb_bridge on TELEM2
(/dev/ttyS2, USART3) when UORB_BRG_CFG is 102 and not by default; with a companion side on
the other end of the cable, the FMU's own topics (the estimator's attitude, the controllers'
setpoints, ...) reach the companion in time and within the link's bandwidth.

One booted FMU (SYS_AUTOSTART 4011, no IO, no world: the stack runs on the ground) for the
module; the companion is a bare system on the same kernel (tests/bridge/rig.py's Side).
"""

from __future__ import annotations

import statistics

import pytest

from fmu.board import FmuV2Board
from board.uart import UartWire
from tests.bridge.rig import Side

MEASURE_S = 2.0


@pytest.fixture(scope="module")
def fmu_and_companion():
    board = FmuV2Board(seed=1, sd_root=None,
                       params={"SYS_AUTOSTART": 4011, "SDLOG_MODE": -1, "SYS_USE_IO": 0,
                               "UORB_BRG_CFG": 102})
    comp = Side(board.kernel, "companion", "/dev/ttyUSB0", None)
    UartWire(board.uarts["USART3"], comp.uart)
    assert comp.cmd("uorb_bridge start -d /dev/ttyUSB0 -r companion") == 0
    board.kernel.run(1_500_000_000)                      # boot
    fmu_bridge = board.system.modules.get("uorb_bridge")
    assert fmu_bridge is not None, "rcS did not start uorb_bridge"
    # latency: FMU publication -> companion publication, per topic sent at every update
    cfg = fmu_bridge.config
    every = [r.topic for r in cfg.fmu_to_companion if r.rate_hz == 0]
    samples: list[int] = []
    pending: dict[str, list[int]] = {t: [] for t in every}

    def on_fmu(topic):
        node = board.platform.orb.node(topic)
        return lambda: pending[topic].append(node.last_publish_ns)

    def on_comp(topic):
        node = comp.orb.node(topic)

        def cb():
            if pending[topic]:
                samples.append(node.last_publish_ns - pending[topic].pop(0))
        return cb

    for t in every:
        board.platform.orb.node(t).callbacks.append(on_fmu(t))
        comp.orb.node(t).callbacks.append(on_comp(t))
    tx0, t0 = fmu_bridge.tx_bytes, board.kernel.now_ns
    board.kernel.run(t0 + int(MEASURE_S * 1e9))
    rate = (fmu_bridge.tx_bytes - tx0) / ((board.kernel.now_ns - t0) / 1e9)
    return board, comp, fmu_bridge, samples, rate


def test_rcs_starts_the_bridge_on_telem2_at_ser_tel2_baud(fmu_and_companion):
    board, comp, fmu_bridge, _s, _r = fmu_and_companion
    assert (fmu_bridge.device, fmu_bridge.baud, fmu_bridge.role) == ("/dev/ttyS2", 921600, "fmu")
    assert board.system.params["SER_TEL2_BAUD"] == 921600
    assert board.uarts["USART3"].config.baud == 921600
    assert fmu_bridge.link_ok and comp.bridge.link_ok


def test_fmu_topics_reach_the_companion(fmu_and_companion):
    board, comp, fmu_bridge, _s, _r = fmu_and_companion
    for topic in ("vehicle_attitude", "vehicle_status", "vehicle_control_mode",
                  "vehicle_local_position", "battery_status"):
        fmu_node, comp_node = board.platform.orb.node(topic), comp.orb.node(topic)
        assert comp_node.publish_count > 0, topic
        if topic == "vehicle_attitude":        # sent at every update: the same last message
            assert comp_node.last.pack() == fmu_node.last.pack()
    d = comp.bridge.decoder.drops
    assert (d.frames, d.lost, fmu_bridge.tx_dropped) == (0, 0, 0)


def test_latency_and_load(fmu_and_companion, capsys):
    """The figures the README states: FMU publication to companion publication (virtual
    time) and the FMU -> companion load at 921600 baud, on the ground (the estimator and the
    controllers at their flight rates)."""
    _b, _c, _fb, samples, rate = fmu_and_companion
    p50 = statistics.median(samples) / 1000
    worst = max(samples) / 1000
    share = rate / (921600 / 10)
    with capsys.disabled():
        print(f"\nuorb_bridge FMU->companion: {len(samples)} messages, latency p50 {p50:.0f} us, "
              f"max {worst:.0f} us; load {rate:.0f} B/s = {share:.0%} of 921600 8N1")
    # a 61-byte attitude frame takes 662 us on the wire; the wake-up comes one character time
    # after the burst, or every 32 bytes of a long one
    assert 600 <= p50 <= 2_000 and worst < 10_000
    assert share < 0.6
