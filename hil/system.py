"""The emulated Pixhawk 1 as one system: FMU and IO boards, the world, and what plugs in.

:func:`build_system` returns an :class:`~hil.orchestrator.Orchestrator` (not started) wired as
``board/wiring.py`` says, with the host devices behind ``"world"``:

* the JSBSim world (truth to the FMU, ESCs from the IO's PWM, or with ``can_escs`` motors 1..4
  from four DroneCAN ESC nodes on CAN1, battery to the power module),
* an RC transmitter with an S.BUS receiver on the IO (the rig's other receiver kinds can be
  added), scripted in virtual time,
* the safety switch,
* optionally the FMU console bridged to a host pty and TCP port (``hil shell``),
* optionally a companion computer on the FMU's TELEM2 (a third board, hil.companion_system;
  docs/companion.md), its console bridged too when the FMU's is, and its topics on ROS.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

from board.wiring import (
    CAN_ESC_NODES,
    PIXHAWK1,
    WORLD,
    Wire,
    uart_link,
    with_can_escs,
    with_fmu_aux,
)
from hil.airframes import HOST
from hil.devices import DeviceHub
from hil.orchestrator import BoardSpec, Orchestrator
from hil.rc import RcRig, Transmitter
from hil.safety_switch import SafetySwitch
from hil.world.fdm import AIRFRAMES, N_MAIN
from hil.worldlink import WorldPorts

__all__ = ["CAN_ESC_PARAMS", "DEFAULT_AIRFRAME", "DEFAULT_QUANTUM_NS", "SystemConfig",
           "build_system"]

#: DJI F450 (the world's JSBSim model)
DEFAULT_AIRFRAME = 4011
#: Lockstep quantum. 500 us: a px4io transaction (request and reply each cross one quantum
#: boundary) takes ~0.9 ms instead of ~1.7 ms at 1 ms, so actuator controls reach the IO at
#: 90 % of the rate an exact link gives (284/s vs 317/s; 1 ms: 231/s), for ~1000 more
#: exchanges per virtual second; 250 us reaches 100 % but costs three times that
#: (docs/architecture.md, Lockstep).
DEFAULT_QUANTUM_NS = 500_000
#: What a PX4 user sets to fly the F450 on DroneCAN ESCs (``SystemConfig.can_escs``): the
#: uavcan driver mixes and sends RawCommand (UAVCAN_ENABLE 3), with the ESC range of the
#: airframe's PWM_MIN/PWM_MAX 1230/1950 us on ESCs calibrated 1000-2000 us, as fractions of
#: 8191: 0.230 x 8191 = 1884, 0.950 x 8191 = 7782 (same idle, same full thrust).
CAN_ESC_PARAMS: dict[str, int] = {"UAVCAN_ENABLE": 3, "UAVCAN_EC_MIN": 1884,
                                  "UAVCAN_EC_MAX": 7782}


@dataclass
class SystemConfig:
    seed: int = 1
    out_dir: str = "out"              # FRAM image and SD card live here
    airframe: int = DEFAULT_AIRFRAME
    quantum_ns: int = DEFAULT_QUANTUM_NS
    mode: str = "process"             # or "local" (one process, for debugging and tests)
    speed: float | None = None        # None: as fast as possible
    params: dict[str, int | float] = field(default_factory=dict)
    console: bool = False             # bridge the FMU console to a pty and TCP port
    rc: str | None = "sbus"           # receiver on the IO: sbus, dsm or ppm (None: no RC)
    trace_path: str | None = None
    fresh_fram: bool = True           # start from erased FRAM (reproducible runs)
    host_clock: bool = False          # let `top` show host time (not deterministic)
    telem_pty: bool = False           # TELEM1/TELEM2 bridged to host pseudo-terminals
    gcs: bool = False                 # a virtual-time GCS on the FMU's UDP port 18570
    udp_bridge: bool = False          # real UDP sockets on 127.0.0.1 (hil fly)
    pipeline: bool = False            # lookahead lockstep (Orchestrator._step_pipelined)
    pin_cpus: bool = False            # the FMU on a CPU of its own (hil.cpu_plan)
    uavcan_nodes: tuple[int | str, ...] = ()  # DroneCAN nodes on the FMU's CAN1 (FmuV2Board)
    #: motors 1..4 on DroneCAN ESCs (nodes 11..14 on CAN1) instead of the IO's PWM outputs,
    #: with CAN_ESC_PARAMS under ``params`` (board/wiring.py with_can_escs)
    can_escs: bool = False
    #: UTC (ns since 1970) the GPS reports at power on; None: the fixed epoch (2024-06-01 12:00,
    #: peripherals.ublox.solution.START_UTC_NS) so logs are byte-identical per seed. hil fly
    #: passes the host's UTC (read here at the edge) so that each run's logs get distinct names.
    gps_utc_start_ns: int | None = None
    #: CAN buses of the FMU reachable from the host (python-can plug-in ``hil``, docs/attaching.md):
    #: each gets an adapter node on the bus (off the bus until a tool attaches) and a
    #: hil.can_interface_host.CanHost, devices["can1"]; ``can_tcp`` adds its TCP endpoint.
    can_hosts: tuple[str, ...] = ()
    can_tcp: bool = False
    #: CAN bus -> python-can bus spec bound to it (``hil fly --can CAN1=virtual:chan0``)
    can_bind: dict[str, str] = field(default_factory=dict)
    #: emulated UART (telem1, telem2, gps, rc) -> pyserial URL or device bound to it
    #: (``hil fly --uart gps=socket://host:port``; hil.bindings_uart)
    uart_bind: dict[str, str] = field(default_factory=dict)
    #: TELEM1/TELEM2 bridges also on TCP ports (the hil:// pyserial URLs of hil fly)
    uart_tcp: bool = False
    #: a companion computer (companion.board, a third board) on the FMU's TELEM2 with the
    #: uORB bridge (FMU UORB_BRG_CFG 102); docs/companion.md
    companion: bool = False
    #: the attitude law on the companion (FMU MC_ATT_IMPL 2, companion mc_att_control);
    #: implies ``companion``
    companion_att: bool = False
    #: the companion's uORB topics on ROS 1 (hil.ros.link.add_ros_link); implies ``companion``
    ros: bool = False


def build_system(cfg: SystemConfig) -> tuple[Orchestrator, dict[str, Any]]:
    """The orchestrator and the host devices by name (world, rc, safety, console)."""
    os.makedirs(cfg.out_dir, exist_ok=True)
    sd_root = os.path.join(cfg.out_dir, "sd")
    os.makedirs(sd_root, exist_ok=True)
    fram = os.path.join(cfg.out_dir, "fram.bin")
    if cfg.fresh_fram and os.path.exists(fram):
        os.remove(fram)
        if os.path.exists(fram + ".sr"):
            os.remove(fram + ".sr")
    params = {"SYS_AUTOSTART": cfg.airframe, **(CAN_ESC_PARAMS if cfg.can_escs else {}),
              **cfg.params}
    uavcan_nodes = (*cfg.uavcan_nodes, *(CAN_ESC_NODES if cfg.can_escs else ()))
    if cfg.can_escs:
        from peripherals.dronecan.spec import check_node_specs

        check_node_specs(uavcan_nodes)  # an ESC or node ID given twice: ValueError
    fmu_kwargs: dict[str, Any] = {"name": "fmu", "seed": cfg.seed, "fram_path": fram,
                                  "sd_root": sd_root, "params": params}
    if cfg.host_clock:
        fmu_kwargs["host_clock"] = "perf_counter"
    if uavcan_nodes:
        fmu_kwargs["uavcan_nodes"] = uavcan_nodes
    if cfg.gps_utc_start_ns is not None:
        fmu_kwargs["gps_utc_start_ns"] = int(cfg.gps_utc_start_ns)
    can_hosts = tuple(dict.fromkeys((*cfg.can_hosts, *cfg.can_bind)))
    if can_hosts:
        fmu_kwargs["host_ports"] = can_hosts
    # The airframe's host side: the world's JSBSim model and the FMU's extra devices (an
    # airframe id without an entry keeps the F450 and the stock board, e.g. SYS_AUTOSTART 0).
    host = HOST.get(cfg.airframe)
    if host is not None and host.fmu_devices:
        fmu_kwargs["extra_devices"] = host.fmu_devices  # names: a trace records plain data
    boards = {"fmu": BoardSpec("fmu.board:FmuV2Board", fmu_kwargs),
              "io": BoardSpec("ioproc.board:IoV2Board", {"name": "io", "seed": cfg.seed})}
    companion_wires: list[Wire] = []
    if cfg.companion or cfg.companion_att or cfg.ros:
        from hil.companion_system import add_companion

        companion_wires = add_companion(cfg, boards, params, cfg.seed)
    world = WorldPorts(seed=cfg.seed, airframe=host.world_model if host is not None else "f450")
    devices: dict[str, Any] = {"world": world}
    hub = DeviceHub(world)
    rc_port = {"sbus": "rc_sbus", "dsm": "rc_dsm", "ppm": "rc_ppm"}
    wiring: list[Wire] = [w for w in PIXHAWK1
                          if not (w.src[0] == WORLD and w.src[1].startswith("rc_"))]
    if cfg.can_escs:
        wiring = with_can_escs(wiring)
    # the FMU's AUX outputs to the channels the world model has there (a VTOL's surfaces)
    model = AIRFRAMES[host.world_model if host is not None else "f450"]
    aux_used = [ch - N_MAIN for ch, o in enumerate(model.outputs)
                if ch >= N_MAIN and o is not None]
    if aux_used:
        wiring = with_fmu_aux(wiring, max(aux_used) + 1)
    if cfg.rc is not None:
        if cfg.rc not in rc_port:
            raise ValueError(f"RC receiver must be one of {sorted(rc_port)}, got {cfg.rc!r}")
        rig = RcRig(Transmitter())
        rig.add(cfg.rc)
        hub.add(rig)
        devices["rc"] = rig
        port = rc_port[cfg.rc]
        wiring.append(next(w for w in PIXHAWK1 if w.src == (WORLD, port)))
    safety = SafetySwitch()
    hub.add(safety)
    devices["safety"] = safety
    if cfg.console:
        from hil.console import SerialBridge

        bridge = SerialBridge("console")
        hub.add(bridge)
        devices["console"] = bridge
        wiring += uart_link(("fmu", "console"), (WORLD, "console"))
        if companion_wires:  # the companion's serial console too (hil shell --board companion)
            cbridge = SerialBridge("companion_console", baud=115_200)
            hub.add(cbridge)
            devices["companion_console"] = cbridge
            wiring += uart_link(("companion", "console"), (WORLD, "companion_console"))
    if companion_wires and "telem2" in cfg.uart_bind:
        raise ValueError("--uart telem2: TELEM2 carries the companion computer's cable")
    if cfg.telem_pty:
        from hil.console import SerialBridge

        for port in ("telem1", "telem2"):
            if port in cfg.uart_bind:
                continue  # bound to a device or URL instead (hil.bindings_uart)
            if port == "telem2" and companion_wires:
                continue  # the companion computer's cable is plugged in there
            # A radio modem on the connector: its serial side is a host pty (57600 8N1, the
            # FMU's default for TELEM links), e.g. mavproxy.py --master=/dev/pts/N.
            tb = SerialBridge(port, baud=57_600, tcp_port=0 if cfg.uart_tcp else None)
            hub.add(tb)
            devices[port] = tb
            wiring += uart_link(("fmu", port), (WORLD, port))
    if cfg.gcs or cfg.udp_bridge:
        from hil.mavlink_bridge import udp_wires

        if cfg.gcs:
            from hil.gcs import GcsClient

            gcs = GcsClient("gcs", fmu_port=18570)
            hub.add(gcs)
            devices["gcs"] = gcs
            wiring += udp_wires("gcs")
        if cfg.udp_bridge:
            from hil.mavlink_bridge import MavlinkUdpBridge

            bridge_dev = MavlinkUdpBridge()
            hub.add(bridge_dev)
            devices["udp"] = bridge_dev
            wiring += udp_wires(bridge_dev.port)
    if can_hosts:
        from hil.bindings_can import add_can_hosts

        wiring += add_can_hosts(cfg, hub, devices, can_hosts)
    wiring += companion_wires
    if cfg.ros:
        from hil.ros.link import add_ros_link

        wiring += add_ros_link(cfg, hub, devices)
    if cfg.uart_bind:
        from hil.bindings_uart import add_uart_bindings

        wiring = add_uart_bindings(cfg, hub, devices, wiring, boards)
    orch = Orchestrator(boards, wiring, world=hub, quantum_ns=cfg.quantum_ns, mode=cfg.mode,
                        speed=cfg.speed, trace_path=cfg.trace_path, pipeline=cfg.pipeline,
                        isolate="fmu" if cfg.pin_cpus and cfg.mode == "process" else None)
    return orch, devices
