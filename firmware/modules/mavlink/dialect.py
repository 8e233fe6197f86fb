"""The one place that names the firmware's MAVLink dialect: ``from ...dialect import mav``.

PX4 builds its MAVLink module with the ``development`` dialect (common plus the messages still
being settled: AVAILABLE_MODES, CURRENT_MODE, ...). pymavlink ships that dialect, but its
2.4.50 release lacks COMPONENT_INFORMATION (395) and COMPONENT_METADATA (397), which
QGroundControl asks for first. ``fmu_hil.xml`` beside this file holds those two definitions
(MAVLink's own, so their CRC_EXTRA bytes are everyone's); this module generates the Python
dialect from it plus pymavlink's ``development.xml`` with pymavlink's own generator (mavgen)
and imports it.

Why generated on first use rather than committed: the generated module is ~1.8 MB of
pymavlink's code, tied to the installed pymavlink (its ``MAVLink`` base classes, its CRC
routines). It is generated once into a cache folder keyed by the SHA-256 of every input (the
XML files and pymavlink's version), in about 0.2 s, and imported from there afterwards, so a
pymavlink upgrade or an edit of the XML regenerates it and nothing stale is ever loaded.
Concurrent first uses (xdist workers, the two board processes) each write a private file and
rename it into place, which is atomic. The cache is ``$FMU_HIL_CACHE`` or
``$XDG_CACHE_HOME/fmu-hil`` (``~/.cache/fmu-hil``), else the temporary folder.

The generated dialect is a superset of ``common``: every message the firmware sent before packs
to the same bytes (same ids, fields and CRC_EXTRA), so logs and links are unchanged; only
messages a client sends that ``common`` did not know are now parsed instead of counted unknown.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib.util
import io
import os
import py_compile
import sys
import tempfile
from pathlib import Path
from types import ModuleType
from typing import Any, Final

__all__ = ["DIALECT_XML", "load", "mav"]

DIALECT_XML: Final = Path(__file__).with_name("fmu_hil.xml")
#: pymavlink's XML files the dialect is built on (development includes common, ...)
_BASE: Final = ("development.xml", "common.xml", "standard.xml", "minimal.xml")
_MODULE_PREFIX: Final = "fmu_hil_mavlink_"


def _cache_dir() -> Path:
    env = os.environ.get("FMU_HIL_CACHE")
    if env:
        return Path(env) / "mavlink"
    xdg = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(xdg) / "fmu-hil" / "mavlink"


def _inputs() -> tuple[Path, str]:
    """pymavlink's dialect folder and the key of every input the generated module depends on."""
    import pymavlink
    from pymavlink.dialects import v20

    base = Path(v20.__file__).parent
    h = hashlib.sha256(str(getattr(pymavlink, "__version__", "")).encode())
    for p in [DIALECT_XML] + [base / name for name in _BASE]:
        h.update(p.name.encode() + b"\0" + p.read_bytes())
    return base, h.hexdigest()[:16]


def _generate(base: Path, key: str, folder: Path) -> Path:
    """Run mavgen on a wrapper XML including development.xml and fmu_hil.xml; the module's
    path (written under a private name first, then renamed into place)."""
    from pymavlink.generator import mavgen
    from pymavlink.generator.mavparse import PROTOCOL_2_0

    folder.mkdir(parents=True, exist_ok=True)
    final = folder / f"{_MODULE_PREFIX}{key}.py"
    with tempfile.TemporaryDirectory(dir=folder) as tmp:
        wrapper = Path(tmp) / f"{_MODULE_PREFIX}{key}.xml"
        wrapper.write_text(
            '<?xml version="1.0"?>\n<mavlink>\n'
            f"  <include>{base / 'development.xml'}</include>\n"
            f"  <include>{DIALECT_XML.resolve()}</include>\n"
            "  <version>3</version>\n  <dialect>0</dialect>\n</mavlink>\n")
        out = Path(tmp) / f"{_MODULE_PREFIX}{key}"
        opts = mavgen.Opts(str(out), wire_protocol=PROTOCOL_2_0, language="Python3",
                           validate=False)
        log = io.StringIO()
        with contextlib.redirect_stdout(log), contextlib.redirect_stderr(log):
            ok = mavgen.mavgen(opts, [str(wrapper)])
        generated = out.with_suffix(".py")
        if not ok or not generated.is_file():
            raise RuntimeError(f"mavgen failed on {DIALECT_XML}:\n{log.getvalue()}")
        os.replace(generated, final)
    return final


def _ensure_bytecode(path: Path) -> None:
    """Write the module's bytecode even where PYTHONDONTWRITEBYTECODE is set (it only stops
    the import system writing it; reading still works): compiling 1.8 MB of source costs each
    process ~0.35 s, loading the bytecode ~0.05 s. py_compile writes atomically."""
    cfile = Path(importlib.util.cache_from_source(str(path)))
    if not cfile.is_file() or cfile.stat().st_mtime < path.stat().st_mtime:
        with contextlib.suppress(OSError, py_compile.PyCompileError):
            py_compile.compile(str(path), cfile=str(cfile), doraise=True)


def load() -> ModuleType:
    """The generated dialect module (generated first if no cached copy matches the inputs)."""
    base, key = _inputs()
    name = _MODULE_PREFIX + key
    cached = sys.modules.get(name)
    if cached is not None:
        return cached
    path: Path | None = None
    for folder in (_cache_dir(), Path(tempfile.gettempdir()) / "fmu-hil-mavlink"):
        candidate = folder / f"{name}.py"
        if candidate.is_file():
            path = candidate
            break
        try:
            path = _generate(base, key, folder)
            break
        except OSError:
            continue   # a read-only cache: try the next place
    if path is None:
        raise RuntimeError("no writable folder for the generated MAVLink dialect "
                           "(set FMU_HIL_CACHE)")
    _ensure_bytecode(path)
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise RuntimeError(f"cannot import the generated MAVLink dialect {path}")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


#: the dialect module (pymavlink's generated API: ``mav.MAVLink``, ``mav.MAVLink_*_message``,
#: ``mav.MAV_*`` constants)
mav: Any = load()
