"""The airframes a run can fly: the FMU's airframe files with what the host puts around them.

The FMU side of an airframe is its ROMFS file (``firmware/romfs/init.d/airframes/NNNN_name``,
selected by ``SYS_AUTOSTART``; its ``@name``, ``@class`` and ``@output`` headers are PX4's).
The host side is here: which JSBSim model of ``hil.world`` the world flies, which devices the
FMU board carries beyond the stock FMUv2 (an airspeed sensor for a plane), and which default
mission ``hil run`` flies. ``hil airframes`` lists them; ``hil run --airframe NAME|ID`` flies one.

A test checks that every airframe file has an entry here and that the file's ``@output`` lines
name what the world model's channels drive.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from firmware import romfs

__all__ = ["AirframeInfo", "CLASSES", "HOST", "HostAirframe", "all_airframes", "fmu_spec",
           "resolve"]

#: PX4's airframe ``@class`` -> the class ``hil airframes --json`` reports
CLASSES: dict[str, str] = {"Copter": "multicopter", "Plane": "fixedwing", "VTOL": "vtol"}


@dataclass(frozen=True)
class HostAirframe:
    """What the host needs to fly an airframe file."""

    world_model: str                    # key of hil.world.fdm.AIRFRAMES
    #: devices added to the stock FMUv2 (keys of board.specs.FMU_V2_OPTIONAL), e.g. the
    #: airspeed sensor a plane carries on the external I2C bus
    fmu_devices: tuple[str, ...] = ()
    #: other names ``--airframe`` accepts besides the id and the file's name
    aliases: tuple[str, ...] = ()


#: SYS_AUTOSTART -> host side. The generic quad flies the F450 model too (same motor order).
HOST: dict[int, HostAirframe] = {
    4001: HostAirframe("f450", aliases=("quad_x",)),
    4011: HostAirframe("f450", aliases=("f450", "quad", "multicopter")),
    2100: HostAirframe("plane", fmu_devices=("ms4525",), aliases=("plane", "fixedwing")),
    13000: HostAirframe("quadplane", fmu_devices=("ms4525",), aliases=("vtol", "quadplane")),
}


@dataclass(frozen=True)
class AirframeInfo:
    id: int                              # SYS_AUTOSTART
    name: str                            # file name without the number: "dji_f450"
    title: str                           # "@name": "DJI Flame Wheel F450"
    vehicle_class: str                   # multicopter, fixedwing or vtol
    file: str                            # FMU path of the airframe script
    outputs: tuple[tuple[str, str], ...]  # "@output" lines: (MAIN1, "aileron"), ...
    host: HostAirframe

    def as_json(self) -> dict[str, Any]:
        return {"id": self.id, "name": self.name, "title": self.title,
                "class": self.vehicle_class, "file": self.file,
                "world_model": self.host.world_model,
                "fmu_devices": list(self.host.fmu_devices),
                "outputs": {o: what for o, what in self.outputs},
                "aliases": list(self.host.aliases)}


def fmu_spec(host: HostAirframe) -> Any:
    """The FMU board's spec for this airframe: the stock FMUv2 with the airframe's devices."""
    from board.specs import FMU_V2, with_optional_devices

    return with_optional_devices(FMU_V2, host.fmu_devices)


def all_airframes() -> list[AirframeInfo]:
    """Every airframe file that has a host entry, by id. A file without one (or an entry
    without a file) is a packaging error the tests catch, not something to list."""
    out = []
    for num, frame in sorted(romfs.airframes().items()):
        host = HOST.get(num)
        if host is None:
            continue
        stem = frame.file.rsplit("/", 1)[1]
        out.append(AirframeInfo(num, stem.split("_", 1)[1], frame.name,
                                CLASSES.get(frame.cls, frame.cls.lower() or "unknown"),
                                frame.file, frame.outputs, host))
    return out


def resolve(key: str | int) -> AirframeInfo:
    """The airframe named by its SYS_AUTOSTART id, its file name (with or without the number),
    its ``@name`` or an alias, case-insensitively. ValueError, listing them, otherwise."""
    frames = all_airframes()
    text = str(key).strip().lower()
    for frame in frames:
        names = {str(frame.id), frame.name, f"{frame.id}_{frame.name}", frame.title.lower(),
                 *frame.host.aliases}
        if text in names:
            return frame
    known = ", ".join(f"{f.id} ({f.name})" for f in frames)
    raise ValueError(f"unknown airframe {key!r}; known: {known} (hil airframes lists them)")
