"""The Pixhawk 1 FMU (PX4 fmu-v2) as a board: the spec's devices on their buses and pins.

Built from :data:`board.specs.FMU_V2`: SPI1 with the MPU6000, L3GD20, LSM303D and MS5611 and
their data-ready lines, SPI2 with the FRAM (persisted in a host file), I2C1 with the GPS
module's HMC5883L, the UARTs (UART4 wired to the u-blox module on the GPS connector), ADC1 with
the power module's voltage and current.

Ports that leave the board (see board/wiring.py):

* ``truth`` (in): the world's truth record; it updates the :class:`Environment` every sensor
  model reads (the physical quantities at the board, not a back door into any chip).
* ``power`` (in): ``(volts, amps)`` at the power module, which the ADC pins see through the
  module's dividers.
* ``io_link`` (USART6), ``telem1``, ``telem2``, ``console``: UARTs.
* CAN1 (PD0 RX / PD1 TX through the transceiver to the CAN connector) and CAN2, each a
  :class:`~board.can.CanBus` at 1 Mbit/s with the FMU's bxCAN controller in sleep mode until
  the uavcan driver enables it. ``uavcan_nodes`` plugs DroneCAN nodes into CAN1: an int is a
  plain node with that ID (:class:`peripherals.uavcan_node.UavcanNode`: NodeStatus at 1 Hz,
  GetNodeInfo), ``"gnss"`` / ``"mag"`` a GNSS receiver (Fix2 at 5 Hz) / compass node
  (:mod:`peripherals.dronecan`) fed by the world's truth, ``"esc1"`` .. ``"esc4"`` ESC nodes
  (RawCommand in, esc.Status out) whose motor commands leave on the ``pwm`` ports
  ``can_esc1..4``, with ``@N`` a configured node ID (``"gnss@0"``, the default, asks the FMU's
  allocator for one). The CAN hardware is
  built on first use (python-can takes ~0.2 s to import): a board whose firmware never touches
  CAN and has no node on it pays nothing, at start or per quantum.
* ``udp_in`` / ``udp_out``: the FMU's network interface as PX4 SITL has one, carrying whole
  datagrams ``(fmu_port, remote_port, bytes)``; the host side (hil/mavlink_bridge.py) owns the
  real sockets. The mavlink module binds its UDP instances in ``udp_handlers``.
* ``failure_request`` (out) / ``failure_reply`` (in): MAV_CMD_INJECT_FAILURE handed to the
  orchestrator's fault injector and its answer (:meth:`FmuV2Board.request_failure`).

Firmware start-up (``firmware=``):

* ``"rcS"`` (default): what the real board does. The FRAM MTD driver starts, the parameters
  load from FRAM, and the nsh shell runs the ROMFS ``rcS``, which starts the drivers and modules
  for the airframe in ``SYS_AUTOSTART``. Parameter overrides given to the board (``params=``)
  are written to FRAM first, as a user would set them and reboot. The shell also serves the
  console UART (UART7, port ``console``) and :meth:`FmuV2Board.ctl_shell`.
* ``"sensors"``: only the sensor drivers (PX4's ``rc.board_sensors``), for driver work.

Either way the drivers started, and the shell modules registered, are those of the spec's
devices (``spec.drivers()``, ``board_modules(spec)``): a board variant
(``spec=FMU_V2.with_device("I2C2", entry).without_device("ms5611")``) builds, registers and
starts its own set with no other change (docs/driver_guide.md, "Adding a device").
* ``"none"``: bare hardware.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from board.adc import Adc
from board.board import Board
from fmu.can import FmuCanSide
from fmu.pwm import FmuPwmSide
from board.gpio import Gpio
from board.i2c import I2cBus
from board.spi import SpiBus
from board.specs import (
    FMU_V2,
    SENSOR_STAGES,
    BoardSpecData,
    model_class,
    with_optional_devices,
)
from board.uart import Uart, UartConfig
from common.truth import TRUTH_FIELDS
from firmware.platform import Platform
from firmware.shell.serial_console import SerialConsole
from peripherals.errors import rng_for
from peripherals.physics import Environment

if TYPE_CHECKING:
    from board.spi import SpiHandle
    from firmware.shell import Shell
    from firmware.system import System

__all__ = ["FmuV2Board", "BOOT_TO_SENSORS_NS"]

#: Virtual time from power-on until the start-up script starts the sensor drivers (NuttX boot,
#: mounting, parameter load). The sensors power up meanwhile (the MPU6000 needs 100 ms).
BOOT_TO_SENSORS_NS = 300_000_000

(_ACCEL, _GYRO, _MAG, _PRESSURE, _TEMPERATURE, _LAT, _LON, _ALT, _VEL, _DIFF_PRESSURE) = (
    TRUTH_FIELDS.index(k) for k in ("accel_body_m_s2", "gyro_rad_s", "mag_body_gauss", "pressure_pa",
                                  "temperature_c", "lat_deg", "lon_deg", "alt_m", "vel_ned_m_s",
                                  "diff_pressure_pa"))

# SPI clocks PX4 uses per device for register access (data reads switch faster themselves).
_SPI_CLOCK = {"mpu6000": 1_000_000, "l3gd20": 11_000_000, "lsm303d": 11_000_000,
              "ms5611": 20_000_000, "fm25v01": 20_000_000}


class FmuV2Board(FmuPwmSide, FmuCanSide, Board):
    """The FMU: STM32F427 with the FMUv2 sensor set."""

    def __init__(self, name: str = "fmu", seed: int = 0, fram_path: str | None = None,
                 sd_root: str | None = None, spec: BoardSpecData = FMU_V2,
                 firmware: str = "rcS", exclude: tuple[str, ...] = (),
                 gps_baud: int = 38_400, params: dict[str, int | float] | None = None,
                 host_clock: Callable[[], float] | None = None,
                 uavcan_nodes: tuple[int | str, ...] = (),
                 gps_utc_start_ns: int | None = None,
                 host_ports: tuple[str, ...] = (),
                 extra_devices: tuple[str, ...] = ()) -> None:
        if firmware not in ("rcS", "sensors", "none"):
            raise ValueError(f"firmware must be 'rcS', 'sensors' or 'none', got {firmware!r}")
        super().__init__(name, seed)
        k = self.kernel
        # an airframe's devices beyond the spec (an airspeed sensor), by name
        spec = with_optional_devices(spec, tuple(extra_devices))
        self.spec = spec
        self.env = Environment()
        self.gpio = Gpio(k, f"{name}.gpio")
        self.platform = Platform(k)
        self.sd_root = sd_root
        self.system: System | None = None
        self.shell: Shell | None = None
        self._param_overrides = dict(params or {})
        self._host_clock = host_clock
        self._ctl_shell: Shell | None = None
        self.reboot_requested = False
        self.spi = {b.name: SpiBus(k, b.name, pclk_hz=b.pclk_hz) for b in spec.spi}
        self.i2c = {b.name: I2cBus(k, b.name, clock_hz=b.clock_hz) for b in spec.i2c}
        self.uarts = {u.name: Uart(k, u.name, UartConfig(baud=u.baud)) for u in spec.uarts}
        self.adc = Adc(k, "ADC1", bits=12, vref_v=3.3)
        self.devices: dict[str, Any] = {}
        self.drivers: dict[str, Any] = {}
        self._excluded = set(exclude)
        self._fram_path = fram_path
        # GPS modules sold for the Pixhawk are usually re-saved at 38400 (a factory u-blox M8
        # starts at 9600, which costs the driver a full baud scan: pass gps_baud=9600).
        self._gps_baud = gps_baud
        # UTC the GPS receiver reports at power on (None: the fixed epoch of reproducible runs;
        # hil fly passes the host's UTC so that log files get distinct names).
        self._gps_utc_start_ns = gps_utc_start_ns
        self._can: dict[str, Any] | None = None
        self.can_ctrl: dict[str, Any] = {}
        self.can_nodes: list[Any] = []
        self.can_host: dict[str, Any] = {}
        self._uavcan_nodes = tuple(uavcan_nodes)
        self._build_devices()
        if self._uavcan_nodes:
            self._build_can()
        self._expose_ports()
        self._build_pwm_outputs()
        for connector in host_ports:
            self._expose_host_port(connector)
        self._power_v = 0.0
        self._power_a = 0.0
        for ch in spec.adc:
            if ch.signal == "battery_voltage":
                self.adc.set_source(ch.channel, lambda t, s=ch.scale: self._power_v / s)
            elif ch.signal == "battery_current":
                self.adc.set_source(ch.channel, lambda t, s=ch.scale: self._power_a / s)
            elif ch.signal == "vdd_5v":
                self.adc.set_source(ch.channel, 5.0 / ch.scale)
        if firmware == "rcS":
            k.call_at(BOOT_TO_SENSORS_NS, self.boot)
        elif firmware == "sensors":
            k.call_at(BOOT_TO_SENSORS_NS, self.start_sensors)

    # -- construction -----------------------------------------------------------------------

    def _rng(self, device: str) -> np.random.Generator:
        return rng_for(self.seed, f"{self.name}.{device}")

    def _build_devices(self) -> None:
        k, env = self.kernel, self.env
        for bus in self.spec.spi:
            spi = self.spi[bus.name]
            for dev in bus.devices:
                if dev.name in self._excluded:
                    continue
                cls = model_class(dev.model)
                pins = [self.gpio.pin(p) for p in dev.drdy]
                if dev.model == "fm25v01":
                    path = self._fram_path
                    if path is not None:
                        os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
                    model = cls(k, name=dev.name, path=path)
                elif dev.model == "lsm303d":
                    model = cls(k, env, self._rng(dev.name), name=dev.name,
                                int1_pin=pins[0] if pins else None,
                                int2_pin=pins[1] if len(pins) > 1 else None)
                elif dev.model == "ms5611":
                    model = cls(k, env, self._rng(dev.name), name=dev.name)
                else:
                    model = cls(k, env, self._rng(dev.name), name=dev.name,
                                drdy_pin=pins[0] if pins else None)
                spi.attach(dev.cs, model)
                self.devices[dev.name] = model
        for ibus in self.spec.i2c:
            for idev in ibus.devices:
                if idev.name in self._excluded:
                    continue
                drdy: dict[str, Any] = {}
                if idev.drdy:
                    drdy["drdy_pin"] = self.gpio.pin(idev.drdy[0])
                model = model_class(idev.model)(k, env, self._rng(idev.name), name=idev.name,
                                                **drdy)
                self.i2c[ibus.name].attach(idev.address, model)
                self.devices[idev.name] = model
        for u in self.spec.uarts:
            if u.external_model is None or u.external_model in self._excluded:
                continue
            # The module plugged into the connector has its own UART, wired to ours.
            from board.uart import UartWire

            cls = model_class(u.external_model)
            extra: dict[str, Any] = {}
            if self._gps_utc_start_ns is not None:
                extra["utc_start_ns"] = self._gps_utc_start_ns
            model = cls(k, env, self._rng(u.role), name=u.role, baud=self._gps_baud, **extra)
            UartWire(self.uarts[u.name], model.uart)
            self.devices[u.role] = model

    def _expose_ports(self) -> None:
        for u in self.spec.uarts:
            if u.port is not None:
                self.expose_uart(u.port, self.uarts[u.name])
        self.expose_input("truth", self._on_truth)
        self.expose_input("power", self._on_power)
        self.hw_inputs |= {"truth", "power"}  # physics at the sensors, dividers at the ADC
        self._emit_reboot = self.expose_output("reboot")
        # MAV_CMD_INJECT_FAILURE: requests to the orchestrator's fault injector and its answers
        self._emit_failure = self.expose_output("failure_request")
        #: the failure_injector module's ``handler(t_ns, (seq, mav_result, text))``
        self.failure_reply_handler: Callable[[int, Any], None] | None = None
        self.expose_input("failure_reply", self._on_failure_reply)
        self.udp_out = self.expose_output("udp_out")
        #: the mavlink module's UDP instances by local port: ``handler(t_ns, remote_port, data)``
        self.udp_handlers: dict[int, Callable[[int, int, bytes], None]] = {}
        self.expose_input("udp_in", self._on_udp)

    def _expose_host_port(self, connector: str) -> None:
        """Let the host reach a connector that is normally closed inside the board (``hil fly
        --can``/``--uart``, the python-can plug-in): a CAN bus (``CAN1``) gets an adapter node
        (:mod:`fmu.can_port`, port ``can1``); a UART with no port of its own (``gps``, its
        module excluded with ``exclude=("ublox_m8",)``) is exposed under its role."""
        if connector in {c.name for c in self.spec.can}:
            from fmu.can_port import CanHostPort

            self.can_host[connector] = CanHostPort(self, self.can[connector], connector.lower())
            return
        for u in self.spec.uarts:
            if u.role == connector and u.port is None:
                if u.external_model is not None and u.external_model not in self._excluded:
                    raise ValueError(f"board {self.name}: {connector} has its {u.external_model} "
                                     f"plugged in; exclude it to expose the connector")
                self.expose_uart(connector, self.uarts[u.name])
                return
        raise ValueError(f"board {self.name}: no connector {connector!r} to expose (CAN buses "
                         f"or UARTs without a port)")

    def _on_udp(self, t_ns: int, payload: tuple[int, int, bytes]) -> None:
        fmu_port, remote_port, data = payload
        handler = self.udp_handlers.get(fmu_port)
        if handler is not None:
            handler(t_ns, remote_port, data)

    def _on_truth(self, t_ns: int, r: tuple) -> None:
        self.env.set_truth(t_ns, r[_ACCEL], r[_GYRO], r[_MAG], r[_PRESSURE], r[_TEMPERATURE],
                           r[_LAT], r[_LON], r[_ALT], r[_VEL])
        self.env.diff_pressure_pa = r[_DIFF_PRESSURE]   # the pitot's, for an airspeed sensor

    def _on_power(self, t_ns: int, record: tuple[float, float]) -> None:
        self._power_v, self._power_a = record

    # -- firmware start-up -------------------------------------------------------------------

    def uart_by_device(self, device: str) -> Uart | None:
        """The UART behind a NuttX device name such as ``/dev/ttyS3``."""
        for u in self.spec.uarts:
            if u.device == device:
                return self.uarts[u.name]
        return None

    def boot(self) -> None:
        """Start the firmware as the real board does: FRAM, parameters, shell, rcS."""
        from firmware import romfs
        from firmware.modules import system_params
        from firmware.platform.module import ModuleRegistry, board_modules
        from firmware.platform.params import Params, ParamStorage
        from firmware.shell import Shell
        from firmware.system import System

        p = self.platform
        registry = ModuleRegistry(None, board_modules(self.spec))
        console = self.uarts["UART7"]

        def to_console(text: str) -> None:
            console.write(text.encode())

        self.system = system = System(p, None, modules=registry, board=self.spec,
                                      sd_root=self.sd_root, reboot=self._reboot_request,
                                      host_clock=self._host_clock, console=to_console, hw=self)
        defs = list(system_params.PARAMS) + registry.param_defs()
        storage = None
        for d in self.spec.drivers("storage"):  # the FRAM's MTD, before the parameters load
            if registry.start(d.command, d.args) == 0 and storage is None:
                mtd: Any = registry.get(d.command)
                storage = ParamStorage(mtd.partition("params"))
                system.waypoints_partition = mtd.partition("waypoints")
        params = Params(p, defs, storage)
        system.params = params
        if self._param_overrides and storage is not None:
            params.load()
            if "SYS_AUTOSTART" in self._param_overrides and \
                    params["SYS_AUTOSTART"] != self._param_overrides["SYS_AUTOSTART"]:
                params.set("SYS_AUTOCONFIG", 1, notify=False)  # as QGC does on a new airframe
            for name, value in self._param_overrides.items():
                params.set(name, value, notify=False)
            params.save()
        elif self._param_overrides:
            for name, value in self._param_overrides.items():
                params.set(name, value, notify=False)
        self.shell = Shell(system, output=to_console)
        SerialConsole(console).attach(self.shell)
        romfs.boot(self.shell)

    def _reboot_request(self, to_bootloader: bool) -> None:
        """``reboot`` / PREFLIGHT_REBOOT: ask the orchestrator (which owns the process) to power
        cycle this board; FRAM, a host file, keeps the parameters."""
        self.platform.warn("reboot", "rebooting in 100 ms")
        self.reboot_requested = True
        # As PX4 does, give the acknowledgement time to leave before going down.
        k = self.kernel
        k.call_later(100_000_000, lambda: self._emit_reboot(k.now_ns, int(to_bootloader)))

    def request_failure(self, seq: int, unit: int, failure_type: int, instance: int) -> None:
        """MAV_CMD_INJECT_FAILURE (the failure_injector module): ask the orchestrator, which owns
        the fault catalogue (hil/faults), to inject a failure as PX4's simulator does in SITL.
        The answer ``(seq, mav_result, text)`` comes back on ``failure_reply`` and goes to
        :attr:`failure_reply_handler`; nothing in the board acts on the request itself."""
        self._emit_failure(self.kernel.now_ns, (seq, unit, failure_type, instance))

    def _on_failure_reply(self, t_ns: int, payload: tuple[int, int, str]) -> None:
        handler = self.failure_reply_handler
        if handler is not None:
            handler(t_ns, payload)

    def spi_handle(self, device: str) -> SpiHandle:
        for bus in self.spec.spi:
            for dev in bus.devices:
                if dev.name == device:
                    return self.spi[bus.name].device(dev.cs, mode=3,
                                                     clock_hz=_SPI_CLOCK.get(dev.model, 1_000_000))
        raise KeyError(device)

    def start_sensors(self) -> dict[str, bool]:
        """Create and start the sensor drivers of this board's spec (PX4's rc.board_sensors),
        in the spec's order, without a shell: each driver's shell module builds it from where
        the spec puts its device (:meth:`DriverModule.build`)."""
        import importlib

        params = self.system.params if self.system is not None else None
        started = {}
        for d in self.spec.drivers(*SENSOR_STAGES):
            if d.command in self._excluded or d.device in self._excluded:
                continue
            mod_name, _, cls_name = d.target.partition(":")
            cls = getattr(importlib.import_module(mod_name), cls_name)
            driver = cls.build(self.platform, self, self.spec.place(d.device),
                               cls.parse_options(d.args), params)
            self.drivers[d.command] = driver
            started[d.command] = driver.start()
        return started

    # -- control calls (tests, shell, fault injection) ---------------------------------------

    def ctl_shell(self, line: str) -> tuple[int, str]:
        """Run one shell command now; returns (exit status, output)."""
        system = self.system
        if self.shell is None or system is None:
            return 1, "nsh: the firmware has not booted the shell (firmware='rcS' boots it)\n"
        from firmware.shell import Shell

        out: list[str] = []
        if self._ctl_shell is None:  # a session of its own, like nsh on another port
            self._ctl_shell = Shell(system)
        self._ctl_shell.output = out.append
        status = self._ctl_shell.execute(line)
        return status, "".join(out)

    def ctl_mavlink(self, what: str = "links") -> list[dict[str, Any]]:
        """Counters of the mavlink links (tests, tools)."""
        mod: Any = self.system.modules.get("mavlink") if self.system is not None else None
        if mod is None:
            return []
        keys = ("rx_messages", "rx_errors", "rx_unknown", "rx_unhandled", "rx_not_for_us",
                "rx_unsigned_rejected", "tx_messages", "tx_dropped", "gcs_heartbeat_us")
        out = []
        for inst in mod.instances:
            d = {k: getattr(inst, k) for k in keys}
            d["rx_lost"] = getattr(inst.transport, "rx_lost", 0)
            d["runs"] = inst.run_count
            d["busy_ns"] = inst.busy_ns_total
            d["max_cost_ns"] = getattr(inst, "max_cost_ns", 0)
            d["port"] = getattr(inst.transport, "local_port", None) or inst.transport.device
            out.append(d)
        return out

    # -- fault hooks of the FMU's chips and CPU (docs/fault_hooks.md) -------------------------

    def ctl_sensor_drift(self, device: str, rate: tuple[float, float, float],
                         period_ms: int = 10) -> None:
        """Ramp a device's bias (``faults.bias_step``) by ``rate`` SI units per second from now,
        updated every ``period_ms`` by a hardware-priority event (a temperature-driven or aging
        drift, a slowly magnetised part); a zero rate stops the ramp where it is."""
        from board.kernel import PRIO_HW

        model = self.devices.get(device)
        if model is None or not hasattr(model, "faults"):
            raise ValueError(f"FMU: no device {device!r} (devices: "
                             f"{', '.join(sorted(self.devices))})")
        rx, ry, rz = (float(v) for v in rate)
        if type(period_ms) is not int or period_ms <= 0:
            raise ValueError(f"FMU: drift update period must be a positive int ms, got "
                             f"{period_ms!r}")
        drifts = self.__dict__.setdefault("_drifts", {})
        old = drifts.pop(device, None)
        if old is not None:
            old.cancel()
        if rx == ry == rz == 0.0:
            return
        k = self.kernel
        faults = model.faults
        base = tuple(faults.bias_step)
        t0 = k.now_ns

        def step() -> None:
            dt = (k.now_ns - t0) * 1e-9
            faults.bias_step = (base[0] + rx * dt, base[1] + ry * dt, base[2] + rz * dt)

        drifts[device] = k.call_every(period_ms * 1_000_000, step, priority=PRIO_HW)

    def ctl_cpu_load(self, wq: str, fraction: float, period_us: int = 1000) -> None:
        """A greedy work item on work queue ``wq`` that burns ``fraction`` of every
        ``period_us`` of CPU time (a runaway module, a busy loop in a driver): the queue's other
        items start late by up to that much. Fraction 0 removes it."""
        from firmware.platform.workqueue import WQ_CONFIGS, WorkItem

        if wq not in WQ_CONFIGS:
            raise ValueError(f"FMU: no work queue {wq!r} (queues: {', '.join(WQ_CONFIGS)})")
        if not 0.0 <= fraction < 1.0 or type(period_us) is not int or period_us <= 0:
            raise ValueError(f"FMU: CPU load needs 0 <= fraction < 1 and a positive int "
                             f"period_us, got {fraction!r}, {period_us!r}")
        hogs = self.__dict__.setdefault("_cpu_hogs", {})
        old = hogs.pop(wq, None)
        if old is not None:
            old.schedule_clear()
        if fraction == 0.0:
            return

        class _Hog(WorkItem):
            runs = 0

            def run(self) -> None:
                self.runs += 1

        hog = _Hog(self.platform, "cpu_hog", wq)
        hog.cpu_cost_ns = round(fraction * period_us * 1000)
        hog.schedule_on_interval(period_us)
        hogs[wq] = hog

    def sensor_rail_devices(self) -> list[str]:
        """The chips on VDD_3V3_SENSORS (switched by PE3): every SPI1 device."""
        return [d.name for b in self.spec.spi if b.name == "SPI1" for d in b.devices
                if d.name in self.devices]

    def ctl_sensor_rail(self, on: bool) -> list[str]:
        """The FMU's sensor 3.3 V rail (VDD_3V3_SENSORS, enabled by PE3) sags (``False``) or
        comes back (``True``): every chip on it loses its supply (no samples, no data-ready,
        MISO left to its pull-up, so reads give 0xFF) and, when the rail returns, goes through
        its power-on reset: registers at reset values, the MPU6000 deaf for 100 ms, the ST
        chips rebooted, the MS5611 reloading its PROM. Returns the chips switched."""
        names = self.sensor_rail_devices()
        for name in names:
            self.devices[name].set_power(bool(on))
        self.sensor_rail_on = bool(on)
        return names

    def ctl_dmesg(self) -> list[tuple[int, int, str, str]]:
        return list(self.platform.dmesg)

    def ctl_topic(self, topic: str, instance: int = 0) -> dict[str, Any] | None:
        """The latest message of a topic instance as a dict (tests and tools); nested
        messages (esc_status.esc) as dicts too, so the answer crosses a process boundary."""
        node = self.platform.orb.node(topic, instance)
        msg = node.last
        if msg is None:
            return None
        return _plain(msg) | {"_count": node.publish_count}

    def ctl_fault(self, device: str, fault: str, value: Any = True) -> None:
        """Set a fault on a device model (see peripherals/faults.py)."""
        setattr(self.devices[device].faults, fault, value)

    def ctl_gps_fault(self, what: str, *args: Any) -> None:
        """A fault of the GPS module on the connector (see peripherals/ublox/receiver.py):
        ``lose_fix`` (bool), ``degrade`` (factor), ``jump`` (north, east, down m), ``jam``
        (0..255), ``set_absent`` (bool)."""
        if what not in ("lose_fix", "degrade", "jump", "jam", "set_absent"):
            raise ValueError(f"no GPS fault {what!r} (lose_fix, degrade, jump, jam, set_absent)")
        getattr(self.devices["gps"], what)(*args)


def _plain(msg: Any) -> dict[str, Any]:
    """A message's fields as a dict, nested messages (single or in arrays) as dicts."""
    out: dict[str, Any] = {}
    for f in msg._fields:
        v = getattr(msg, f)
        if hasattr(v, "_fields"):
            v = _plain(v)
        elif isinstance(v, list) and v and hasattr(v[0], "_fields"):
            v = [_plain(e) for e in v]
        out[f] = v
    return out
