"""``mixer load DEVICE FILE``: hand a mixer definition to the output driver (PX4's systemcmd).

On the Pixhawk 1 the main outputs belong to the IO coprocessor, so ``/dev/pwm_output0`` is the
px4io driver, which uploads the file to the IO's mixer page. The FMU's own outputs
(``/dev/px4fmu``, ``/dev/pwm_output1`` beside the IO: the AUX rail) are driven by the ``fmu``
module when it is running; ``/dev/uavcan/esc`` is
the uavcan driver's CAN ESC output (``UAVCAN_ENABLE`` 3).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Final

if TYPE_CHECKING:
    from firmware.shell.interpreter import Shell

__all__ = ["COMMANDS"]

_DEVICES: Final = {"/dev/pwm_output0": ("px4io", "fmu"), "/dev/px4io": ("px4io",),
            "/dev/pwm_output1": ("fmu",), "/dev/px4fmu": ("fmu",),
            "/dev/uavcan/esc": ("uavcan",)}


def cmd_mixer(sh: Shell, argv: list[str]) -> int:
    if len(argv) != 4 or argv[1] != "load":
        sh.print("usage: mixer load <device> <file>   (device: /dev/pwm_output0)")
        return 1
    device, path = argv[2], argv[3]
    owners = _DEVICES.get(device)
    if owners is None:
        sh.print(f"mixer: unknown device {device}; known: {', '.join(sorted(_DEVICES))}")
        return 1
    registry = sh.system.modules
    for name in owners:
        if registry.is_running(name):
            return registry.command(name, ["mixer", path])
    sh.print(f"mixer: no output driver running for {device} (start px4io or fmu first)")
    return 1


COMMANDS: Final = {"mixer": (cmd_mixer, "mixer load <device> <file>: load a mixer into an output driver")}
