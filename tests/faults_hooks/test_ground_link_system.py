"""Ground-link faults against the real FMU: the commander's data-link loss, and a flood the
mavlink receiver must survive."""

from __future__ import annotations

import pytest

from hil.faults import FaultError

from .conftest import S

pytestmark = pytest.mark.slow
DL_LOSS_T_S = 10           # COM_DL_LOSS_T default


def _status(rig):
    return rig.orch.call("fmu", "topic", "vehicle_status")


def test_uplink_loss_sets_data_link_lost_after_com_dl_loss_t_and_recovers(rig):
    gcs = rig.dev["gcs"]
    rig.run_s(1.0)
    assert not _status(rig)["data_link_lost"]
    t0 = rig.orch.t_ns
    last_hb = (t0 // S) * S          # the GCS's 1 Hz heartbeats go at whole seconds
    rig.start("link.datalink_loss", "uplink")
    took = rig.run_until(lambda: _status(rig)["data_link_lost"], timeout_s=DL_LOSS_T_S + 2,
                         step_s=0.05)
    lost_at = t0 + took * S
    # lost COM_DL_LOSS_T after the last heartbeat that got through (commander runs at 100 Hz)
    assert DL_LOSS_T_S - 0.05 <= (lost_at - last_hb) / S <= DL_LOSS_T_S + 1.1
    assert gcs.lost_up > 0
    # the downlink still works: the GCS hears the vehicle's heartbeats
    n = gcs.counts.get("HEARTBEAT", 0)
    rig.run_s(1.5)
    assert gcs.counts["HEARTBEAT"] > n
    rig.stop("link.datalink_loss", "uplink", None)
    rig.run_until(lambda: not _status(rig)["data_link_lost"], timeout_s=2)
    assert _status(rig)["data_link_lost_counter"] >= 1


def test_downlink_loss_blinds_the_gcs_only(rig):
    gcs = rig.dev["gcs"]
    rig.start("link.datalink_loss", "downlink")
    n = gcs.counts.get("HEARTBEAT", 0)
    rig.run_s(1.5)
    assert gcs.counts.get("HEARTBEAT", 0) == n and gcs.lost_down > 0
    assert not _status(rig)["data_link_lost"]
    rig.stop("link.datalink_loss", "downlink", None)
    rig.run_s(1.5)
    assert gcs.counts["HEARTBEAT"] > n


@pytest.mark.parametrize("kind", ["param_request_list", "garbage"])
def test_a_flood_is_dropped_at_the_receive_queue_and_the_real_gcs_still_gets_through(rig, kind):
    gcs = rig.dev["gcs"]
    rig.run_s(1.0)
    n0 = gcs.counts.get("ATTITUDE", 0)
    rig.run_s(2.0)
    calm = gcs.counts.get("ATTITUDE", 0) - n0          # the stream's rate without a flood
    assert calm >= 15
    rig.start("link.mavlink_flood", rate_hz=20000.0, kind=kind, size=200)
    n_att = gcs.counts.get("ATTITUDE", 0)
    rig.run_s(2.0)
    assert gcs.flood_sent >= 39_900
    links = {d["port"]: d for d in rig.orch.call("fmu", "mavlink")}
    udp = links[18570]
    assert udp["rx_lost"] > 20_000           # the socket queue (64) overflowed and dropped
    assert "fmu" not in rig.orch.dead
    # its streams go on (a flood of parameter requests costs the stream some bandwidth)
    assert gcs.counts.get("ATTITUDE", 0) - n_att >= 0.8 * calm
    # and a request from the real GCS still gets answered during the flood
    assert gcs.param_get("COM_DL_LOSS_T", timeout_s=3.0) == DL_LOSS_T_S
    rig.stop("link.mavlink_flood", "", None, rate_hz=20000.0, kind=kind, size=200)
    sent = gcs.flood_sent
    rig.run_s(0.2)
    assert gcs.flood_sent == sent
    with pytest.raises(FaultError, match="kind"):
        rig.start("link.mavlink_flood", kind="tsunami")
