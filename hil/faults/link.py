"""Ground-link faults: the telemetry radio between the ground station and the vehicle.

They act on the virtual-time GCS (``rig.dev["gcs"]``, hil/gcs.py), i.e. on the radio link
itself: the FMU's mavlink module notices as it would on a real vehicle (no GCS heartbeat for
COM_DL_LOSS_T, a receive queue that overflows).
"""

from __future__ import annotations

from typing import Any

from hil.faults import Rig, fault_kind
from hil.faults._rig import device, number

DIRECTIONS = ("both", "uplink", "downlink")


@fault_kind("link.datalink_loss", level="link", targets=DIRECTIONS,
            doc="The telemetry link stops carrying traffic: both ways (radio out of range), "
                "uplink only (nothing from the GCS reaches the vehicle: no GCS heartbeat) or "
                "downlink only (the GCS goes blind; the vehicle still hears it). With the "
                "uplink gone the commander declares the data link lost COM_DL_LOSS_T seconds "
                "after the last GCS heartbeat (vehicle_status.data_link_lost) and, once "
                "in the air, takes NAV_DLL_ACT.")
def datalink_loss(rig: Rig, target: str, params: dict[str, Any], t_ns: int) -> Any:
    gcs = device(rig, "gcs", "link.datalink_loss")
    gcs.set_link_loss(up=target in ("both", "uplink"), down=target in ("both", "downlink"))
    return None


@datalink_loss.stopper
def _datalink_loss_stop(rig: Rig, target: str, params: dict[str, Any], t_ns: int,
                        token: Any) -> None:
    device(rig, "gcs", "link.datalink_loss").set_link_loss(False, False)


@fault_kind("link.mavlink_flood", level="link", rate_hz=2000.0, kind="heartbeat", size=0,
            doc="A flood of traffic towards the vehicle at rate_hz datagrams per second: valid "
                "heartbeats from another GCS, whole-parameter-list requests, statustexts, or "
                "garbage bytes. The FMU's receive queue (64 datagrams between two runs of the "
                "mavlink instance, a socket buffer) drops what it cannot hold; the receiver "
                "must survive, keep parsing the real GCS's messages and keep its streams.")
def mavlink_flood(rig: Rig, target: str, params: dict[str, Any], t_ns: int) -> Any:
    name = "link.mavlink_flood"
    gcs = device(rig, "gcs", name)
    try:
        gcs.flood(number(params, "rate_hz", name, 0.0, 1e6), str(params["kind"]),
                  int(number(params, "size", name, 0, 65_000)))
    except ValueError as exc:
        from hil.faults import FaultError
        raise FaultError(f"fault {name}: {exc}") from None
    return None


@mavlink_flood.stopper
def _mavlink_flood_stop(rig: Rig, target: str, params: dict[str, Any], t_ns: int,
                        token: Any) -> None:
    device(rig, "gcs", "link.mavlink_flood").flood(0)
