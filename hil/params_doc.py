"""``hil params``: the parameter reference, generated from every module's declarations."""

from __future__ import annotations

import sys
from functools import lru_cache
from pathlib import Path

from firmware.modules import system_params
from firmware.platform.module import ModuleRegistry
from firmware.platform.params import ParamDef, markdown_reference

__all__ = ["all_param_defs", "param_def", "main", "REFERENCE"]

#: the generated page kept in the repository (a test checks it is current)
REFERENCE = Path(__file__).resolve().parent.parent / "docs" / "parameter_reference.md"


def all_param_defs() -> list[ParamDef]:
    defs: dict[str, ParamDef] = {d.name: d for d in system_params.PARAMS}
    for d in ModuleRegistry(None).param_defs():
        defs.setdefault(d.name, d)
    return sorted(defs.values(), key=lambda d: d.name)


@lru_cache(maxsize=1)
def _defs_by_name() -> dict[str, ParamDef]:
    return {d.name: d for d in all_param_defs()}


def param_def(name: object) -> ParamDef | None:
    """The declaration of parameter ``name`` (the FMU's system parameters and every
    module's), or None if nothing declares it (or it is not a string): what the scenario
    loader and ``--param`` check names and values against before anything boots. The
    table is built once (it instantiates every module's declarations)."""
    return _defs_by_name().get(name) if isinstance(name, str) else None


def main(out: str | None = None) -> int:
    text = markdown_reference(all_param_defs())
    if out is None:
        sys.stdout.write(text)
    else:
        Path(out).write_text(text)
        print(f"hil params: wrote {out}", file=sys.stderr)
    return 0
