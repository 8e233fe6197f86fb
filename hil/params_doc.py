"""``hil params``: the parameter reference, generated from every module's declarations."""

from __future__ import annotations

import sys
from pathlib import Path

from firmware.modules import system_params
from firmware.platform.module import ModuleRegistry
from firmware.platform.params import ParamDef, markdown_reference

__all__ = ["all_param_defs", "main", "REFERENCE"]

#: the generated page kept in the repository (a test checks it is current)
REFERENCE = Path(__file__).resolve().parent.parent / "docs" / "parameter_reference.md"


def all_param_defs() -> list[ParamDef]:
    defs: dict[str, ParamDef] = {d.name: d for d in system_params.PARAMS}
    for d in ModuleRegistry(None).param_defs():
        defs.setdefault(d.name, d)
    return sorted(defs.values(), key=lambda d: d.name)


def main(out: str | None = None) -> int:
    text = markdown_reference(all_param_defs())
    if out is None:
        sys.stdout.write(text)
    else:
        Path(out).write_text(text)
        print(f"hil params: wrote {out}", file=sys.stderr)
    return 0
