"""The ROMFS of the FMU: startup scripts and airframes in nsh syntax, mounted at ``/etc``.

The files are plain text in this folder (``init.d/rcS``, ``init.d/rc.*``,
``init.d/airframes/NNNN_name``, ``mixers/``); the shell maps ``/etc/...`` here. This module only
finds them: :func:`airframes` reads the ``# @name`` headers (as PX4's airframe tooling does) so a
tool or test can list what ``SYS_AUTOSTART`` may select, and :func:`boot` runs ``rcS``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from firmware.shell import Shell

__all__ = ["RCS", "ROMFS_ROOT", "Airframe", "airframes", "boot"]

#: host folder mounted at /etc
ROMFS_ROOT = Path(__file__).resolve().parent
#: the startup script, as an FMU path
RCS = "/etc/init.d/rcS"

_AIRFRAME_FILE = re.compile(r"^(\d+)_([A-Za-z0-9_]+)$")


@dataclass(frozen=True)
class Airframe:
    autostart: int      # the SYS_AUTOSTART value that selects it
    file: str           # FMU path of the script
    name: str           # "# @name" header
    type: str           # "# @type" header


def airframes(root: Path = ROMFS_ROOT) -> dict[int, Airframe]:
    """Airframes by SYS_AUTOSTART value, from the file names and their headers."""
    out: dict[int, Airframe] = {}
    folder = root / "init.d" / "airframes"
    for f in sorted(folder.iterdir()) if folder.is_dir() else []:
        m = _AIRFRAME_FILE.match(f.name)
        if not m:
            continue
        head = {k: v.strip() for k, v in re.findall(r"^#\s*@(\w+)\s+(.*)$", f.read_text(),
                                                     re.MULTILINE)}
        out[int(m.group(1))] = Airframe(int(m.group(1)), f"/etc/init.d/airframes/{f.name}",
                                        head.get("name", m.group(2)), head.get("type", ""))
    return out


def boot(shell: Shell) -> int:
    """Run the startup script on ``shell``; returns its exit status."""
    return shell.run_file(RCS)
