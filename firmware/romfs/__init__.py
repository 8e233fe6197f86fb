"""The ROMFS of the FMU: startup scripts and airframes in nsh syntax, mounted at ``/etc``.

The files are plain text in this folder (``init.d/rcS``, ``init.d/rc.*``,
``init.d/airframes/NNNN_name``, ``mixers/``); the shell maps ``/etc/...`` here. This module only
finds them: :func:`airframes` reads the ``# @name`` headers (as PX4's airframe tooling does) so a
tool or test can list what ``SYS_AUTOSTART`` may select, and :func:`boot` runs ``rcS``.

Some lines are written by the board rather than by hand: ``@board_sensors STAGE`` (in
``rc.sensors``) becomes one ``DRIVER start [options]`` line per device of that driver stage in
the board's spec (:meth:`board.specs.BoardSpecData.drivers`: ``baro``, then ``sensors``), in
the spec's order, when the shell reads the file (:func:`expand`). PX4 writes that list per
board (``rc.board_sensors``); here the board's spec is the one place a device is put on a
board, so a board variant starts its own drivers.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from board.specs import BoardSpecData
    from firmware.shell import Shell

__all__ = ["RCS", "ROMFS_ROOT", "BOARD_SENSORS", "Airframe", "airframes", "boot", "expand"]

#: host folder mounted at /etc
ROMFS_ROOT = Path(__file__).resolve().parent
#: the startup script, as an FMU path
RCS = "/etc/init.d/rcS"

#: the ROMFS line replaced by the board's sensor driver lines
BOARD_SENSORS = "@board_sensors"

_AIRFRAME_FILE = re.compile(r"^(\d+)_([A-Za-z0-9_]+)$")


@dataclass(frozen=True)
class Airframe:
    autostart: int      # the SYS_AUTOSTART value that selects it
    file: str           # FMU path of the script
    name: str           # "# @name" header
    type: str           # "# @type" header
    cls: str = ""       # "# @class" header: Copter, Plane or VTOL (PX4's airframe classes)
    #: "# @output MAIN1 aileron" headers: (output, what it drives), in file order
    outputs: tuple[tuple[str, str], ...] = ()


def airframes(root: Path = ROMFS_ROOT) -> dict[int, Airframe]:
    """Airframes by SYS_AUTOSTART value, from the file names and their headers."""
    out: dict[int, Airframe] = {}
    folder = root / "init.d" / "airframes"
    for f in sorted(folder.iterdir()) if folder.is_dir() else []:
        m = _AIRFRAME_FILE.match(f.name)
        if not m:
            continue
        text = f.read_text()
        head = {k: v.strip() for k, v in re.findall(r"^#\s*@(\w+)\s+(.*)$", text, re.MULTILINE)
                if k != "output"}
        outputs = tuple((o, what.strip()) for o, what in
                        re.findall(r"^#\s*@output\s+(\S+)\s+(.*)$", text, re.MULTILINE))
        out[int(m.group(1))] = Airframe(int(m.group(1)), f"/etc/init.d/airframes/{f.name}",
                                        str(head.get("name", m.group(2))),
                                        head.get("type", ""), head.get("class", ""), outputs)
    return out


def boot(shell: Shell) -> int:
    """Run the startup script on ``shell``; returns its exit status."""
    return shell.run_file(RCS)


def board_sensor_lines(board: BoardSpecData | None, *stages: str) -> list[str]:
    """The nsh lines that start the drivers of ``board`` (None: the FMUv2's spec) of the given
    stages (none given: the sensor stages), in spec order."""
    if board is None:
        from board.specs import FMU_V2

        board = FMU_V2
    from board.specs import SENSOR_STAGES

    return [d.line for d in board.drivers(*(stages or SENSOR_STAGES))]


def expand(text: str, board: BoardSpecData | None) -> str:
    """A ROMFS file's text with each ``@board_sensors [STAGE]`` line replaced by
    :func:`board_sensor_lines` (other text unchanged)."""
    if BOARD_SENSORS not in text:
        return text
    out: list[str] = []
    for line in text.split("\n"):
        words = line.split()
        if words and words[0] == BOARD_SENSORS:
            out.extend(board_sensor_lines(board, *words[1:]))
        else:
            out.append(line)
    return "\n".join(out)
