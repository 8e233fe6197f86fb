"""ROS 1 message types for the uORB topics: a real ``px4_msgs`` package made with genpy.

The topics are declared once, in ``firmware/msg/*.msg`` (PX4 syntax). From them this module
writes a ROS package ``px4_msgs`` under ``~/.cache/fmu-hil/ros`` (``$XDG_CACHE_HOME`` is
honoured), the way catkin would build one:

    ~/.cache/fmu-hil/ros/px4_msgs/package.xml
    ~/.cache/fmu-hil/ros/px4_msgs/msg/VehicleAttitude.msg ...          (ROS .msg files)
    ~/.cache/fmu-hil/ros/px4_msgs/src/px4_msgs/msg/_VehicleAttitude.py (genpy's classes)

so a tool in another process (``rostopic echo /fmu/out/vehicle_attitude``, ``rosmsg show``,
``rosbag``) loads the types once a user sets (``python -m hil.ros.msggen`` prints the lines)::

    export ROS_PACKAGE_PATH=~/.cache/fmu-hil/ros:$ROS_PACKAGE_PATH   # rospack finds px4_msgs
    export PYTHONPATH=$PYTHONPATH:~/.cache/fmu-hil/ros/px4_msgs/src   # Python imports it

(roslib looks the package up with rospack before importing it, so both are needed.)
The package is regenerated when a .msg file (or this generator) changes: a digest of the
generated ROS definitions is kept in the package and compared on every :func:`ensure_package`.

Type mapping (PX4 -> ROS 1): the numeric types and ``bool`` keep their names; PX4's ``byte``
(uORB stores it unsigned) becomes ``uint8``; ``char[N]`` (fixed text) becomes ``string`` (ROS 1
has no fixed-length string; a longer text coming from ROS is refused by the converter); a
nested type ``position_setpoint`` becomes ``PositionSetpoint`` of the same package; fixed
arrays stay fixed; constants (``ORB_QUEUE_LENGTH`` too) are kept. Type names are PX4's
``px4_msgs`` names (``vehicle_rates_setpoint`` -> ``px4_msgs/VehicleRatesSetpoint``); every
topic of a type (``# TOPICS``) uses that type. Without ``char`` fields a ROS message's
serialized bytes are exactly uORB's ``pack()`` (both little-endian, packed, fixed arrays
without length), which the tests use as a second check of the mapping.

Converters (:func:`converter`): uORB message object <-> genpy message, field by field, nested
types and arrays included. ROS -> uORB is outside input: a value the uORB field cannot hold
(wrong array length, integer out of range, text too long or not Latin-1) raises
:class:`ConversionError` naming the field, and the ROS node counts and drops the message.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import importlib
import os
import shutil
import sys
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any, Callable, Final

from firmware.platform.msgdef import (MessageDef, MessageRegistry, default_registry,
                                      snake_to_camel)

__all__ = ["PACKAGE", "ConversionError", "Converter", "GeneratedPackage", "cache_root",
           "converter", "ensure_package", "env_lines", "ros_msg_text", "ros_python_path",
           "ros_type", "ros_class"]

PACKAGE: Final = "px4_msgs"
#: bump when the generated files change for reasons other than the .msg files
GENERATOR_VERSION: Final = "2"
#: where Debian installs rospy, genpy and genmsg (appended to sys.path, never prepended, so the
#: venv's own packages win)
DEBIAN_ROS_PATH: Final = "/usr/lib/python3/dist-packages"
_DIGEST_FILE: Final = ".fmu_hil_digest"

#: PX4 primitive -> ROS 1 primitive
ROS_PRIMITIVE: Final[dict[str, str]] = {
    "bool": "bool", "byte": "uint8", "char": "string", "uint8": "uint8", "int8": "int8",
    "uint16": "uint16", "int16": "int16", "uint32": "uint32", "int32": "int32",
    "uint64": "uint64", "int64": "int64", "float32": "float32", "float64": "float64",
}

_INT_RANGE: Final[dict[str, tuple[int, int]]] = {
    "byte": (0, 0xFF), "uint8": (0, 0xFF), "int8": (-0x80, 0x7F),
    "uint16": (0, 0xFFFF), "int16": (-0x8000, 0x7FFF),
    "uint32": (0, 0xFFFFFFFF), "int32": (-0x80000000, 0x7FFFFFFF),
    "uint64": (0, 0xFFFFFFFFFFFFFFFF), "int64": (-0x8000000000000000, 0x7FFFFFFFFFFFFFFF),
}


class ConversionError(ValueError):
    """A ROS message holds a value its uORB field cannot (the message names the field)."""


def ros_python_path() -> None:
    """Make Debian's rospy/genpy importable from the venv (appended: the venv wins)."""
    try:
        import genpy  # noqa: F401
    except ImportError:
        if DEBIAN_ROS_PATH not in sys.path:
            sys.path.append(DEBIAN_ROS_PATH)


def cache_root() -> Path:
    """``~/.cache/fmu-hil/ros`` (or under ``$XDG_CACHE_HOME``)."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "fmu-hil" / "ros"


def ros_type(mdef: MessageDef | str) -> str:
    """The ROS type of a uORB message type: ``px4_msgs/VehicleRatesSetpoint``."""
    name = mdef if isinstance(mdef, str) else mdef.name
    return f"{PACKAGE}/{snake_to_camel(name)}"


def _fmt_const(ctype: str, value: Any) -> str:
    if ctype == "bool":
        return "1" if value else "0"
    if ctype in ("float32", "float64"):
        return repr(float(value))
    return str(int(value))


def ros_msg_text(mdef: MessageDef) -> str:
    """The ROS 1 .msg definition of a uORB message type (comments and units kept)."""
    src = Path(mdef.source).name if mdef.source else f"{mdef.name}.msg"
    out = [f"# Generated by fmu-hil from firmware/msg/{src}; do not edit.",
           f"# uORB topics: {' '.join(mdef.topics)}"]
    for f in mdef.fields:
        if f.is_primitive:
            base = ROS_PRIMITIVE[f.type]
            arr = "" if f.type == "char" or not f.array else f"[{f.array}]"
        else:
            base = snake_to_camel(f.type)
            arr = f"[{f.array}]" if f.array else ""
        note = f"  # {f.comment}" if f.comment else ""
        if f.type == "char":
            note = f"  # at most {f.array} characters (uORB char[{f.array}])" + (
                f"; {f.comment}" if f.comment else "")
        out.append(f"{base}{arr} {f.name}{note}")
    for cname, (ctype, value) in mdef.constants.items():
        out.append(f"{ROS_PRIMITIVE[ctype]} {cname} = {_fmt_const(ctype, value)}")
    return "\n".join(out) + "\n"


def _package_xml() -> str:
    return ("<?xml version=\"1.0\"?>\n<package format=\"2\">\n"
            f"  <name>{PACKAGE}</name>\n  <version>0.0.0</version>\n"
            "  <description>uORB message types of fmu-hil (generated from firmware/msg by "
            "hil.ros.msggen)</description>\n"
            "  <maintainer email=\"fmu-hil@example.com\">fmu-hil</maintainer>\n"
            "  <license>BSD</license>\n  <buildtool_depend>catkin</buildtool_depend>\n"
            "  <build_depend>message_generation</build_depend>\n"
            "  <exec_depend>message_runtime</exec_depend>\n</package>\n")


@dataclass(frozen=True)
class GeneratedPackage:
    """Where the generated package is: ``root`` goes on ROS_PACKAGE_PATH, ``python_dir`` on
    PYTHONPATH."""

    root: Path          # the folder holding px4_msgs/
    package_dir: Path   # root/px4_msgs
    python_dir: Path    # root/px4_msgs/src
    digest: str
    regenerated: bool

    def env(self) -> dict[str, str]:
        """The variables another process needs to load the types (merged with os.environ)."""
        def join(var: str, item: str, first: bool) -> str:
            old = [p for p in os.environ.get(var, "").split(os.pathsep) if p and p != item]
            return os.pathsep.join([item] + old if first else old + [item])
        return {"ROS_PACKAGE_PATH": join("ROS_PACKAGE_PATH", str(self.root), True),
                "PYTHONPATH": join("PYTHONPATH", str(self.python_dir), False)}


def _definitions(registry: MessageRegistry) -> dict[str, str]:
    return {snake_to_camel(name): ros_msg_text(m) for name, m in sorted(registry.messages.items())}


def _digest(defs: dict[str, str]) -> str:
    h = hashlib.sha256(f"fmu-hil msggen {GENERATOR_VERSION}\n".encode())
    for name, text in sorted(defs.items()):
        h.update(f"{name}\n{text}\0".encode())
    return h.hexdigest()


@contextlib.contextmanager
def _locked(root: Path) -> Iterator[None]:
    """One generator at a time per cache folder (pytest-xdist workers, two nodes starting)."""
    root.mkdir(parents=True, exist_ok=True)
    with open(root / ".lock", "a+") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


def _generate(target: Path, defs: dict[str, str], digest: str) -> None:
    """Write the package (msg files, genpy classes) into ``target`` (a fresh folder)."""
    ros_python_path()
    import genmsg
    import genmsg.command_line  # noqa: F401
    from genpy.generate_initpy import write_modules
    from genpy.generator import MsgGenerator

    msg_dir = target / "msg"
    py_pkg = target / "src" / PACKAGE
    py_msg = py_pkg / "msg"
    msg_dir.mkdir(parents=True)
    py_msg.mkdir(parents=True)
    (target / "package.xml").write_text(_package_xml())
    files = []
    for name, text in sorted(defs.items()):
        p = msg_dir / f"{name}.msg"
        p.write_text(text)
        files.append(str(p))
    search_path = {PACKAGE: [str(msg_dir)]}
    # genpy prints its own errors to stderr; its return code says whether any failed
    rc = MsgGenerator().generate_messages(PACKAGE, files, str(py_msg), search_path)
    if rc:
        raise RuntimeError(f"genpy failed to generate {PACKAGE} (see the errors above)")
    write_modules(str(py_msg))
    (py_pkg / "__init__.py").write_text("")
    (target / _DIGEST_FILE).write_text(digest + "\n")
    del genmsg


def ensure_package(root: Path | str | None = None,
                   registry: MessageRegistry | None = None) -> GeneratedPackage:
    """The generated package, (re)written first when missing or out of date."""
    reg = registry or default_registry()
    base = Path(root) if root is not None else cache_root()
    defs = _definitions(reg)
    digest = _digest(defs)
    pkg_dir = base / PACKAGE
    regenerated = False
    with _locked(base):
        stamp = pkg_dir / _DIGEST_FILE
        current = stamp.read_text().strip() if stamp.is_file() else ""
        if current != digest:
            tmp = Path(tempfile.mkdtemp(prefix=".gen-", dir=base))
            try:
                _generate(tmp / PACKAGE, defs, digest)
                old = base / f".old-{os.getpid()}"
                if pkg_dir.exists():
                    os.replace(pkg_dir, old)
                os.replace(tmp / PACKAGE, pkg_dir)
                shutil.rmtree(old, ignore_errors=True)
            finally:
                shutil.rmtree(tmp, ignore_errors=True)
            regenerated = True
    return GeneratedPackage(base, pkg_dir, pkg_dir / "src", digest, regenerated)


def env_lines(pkg: GeneratedPackage) -> list[str]:
    """Shell lines that let another process (rostopic, rosbag, a user's node) load the types."""
    return [f"export ROS_PACKAGE_PATH={pkg.root}${{ROS_PACKAGE_PATH:+:$ROS_PACKAGE_PATH}}",
            f"export PYTHONPATH=${{PYTHONPATH:+$PYTHONPATH:}}{pkg.python_dir}"]


def import_package(pkg: GeneratedPackage) -> ModuleType:
    """``px4_msgs.msg`` of ``pkg``, imported in this process (a stale import is replaced)."""
    ros_python_path()
    path = str(pkg.python_dir)
    loaded = sys.modules.get(f"{PACKAGE}.msg")
    if loaded is not None and getattr(loaded, "_fmu_hil_digest", None) == pkg.digest:
        return loaded
    for name in [n for n in sys.modules if n == PACKAGE or n.startswith(PACKAGE + ".")]:
        del sys.modules[name]
    if path not in sys.path:
        sys.path.append(path)
    importlib.invalidate_caches()
    mod = importlib.import_module(f"{PACKAGE}.msg")
    origin = Path(mod.__file__ or "").resolve()
    if pkg.python_dir.resolve() not in origin.parents:
        raise ImportError(f"{PACKAGE}.msg came from {origin}, not from {pkg.python_dir} "
                          f"(another {PACKAGE} is earlier on sys.path)")
    mod._fmu_hil_digest = pkg.digest  # type: ignore[attr-defined]
    return mod


_LOADED: dict[str, tuple[GeneratedPackage, ModuleType]] = {}


def load(root: Path | str | None = None) -> tuple[GeneratedPackage, ModuleType]:
    """The package (generated if needed) and its imported ``px4_msgs.msg``, once per process."""
    key = str(Path(root) if root is not None else cache_root())
    hit = _LOADED.get(key)
    if hit is None:
        pkg = ensure_package(root)
        hit = _LOADED[key] = (pkg, import_package(pkg))
    return hit


def ros_class(topic: str, registry: MessageRegistry | None = None) -> type:
    """The genpy class carrying a uORB topic (``vehicle_attitude`` -> VehicleAttitude)."""
    reg = registry or default_registry()
    _pkg, mod = load()
    cls: type = getattr(mod, snake_to_camel(reg.topic(topic).name))
    return cls


# -- converters --------------------------------------------------------------------------------

def _check_int(v: Any, ptype: str, where: str) -> int:
    if isinstance(v, bool):
        return int(v)
    if not isinstance(v, int):
        raise ConversionError(f"{where}: {v!r} is not an integer")
    lo, hi = _INT_RANGE[ptype]
    if not lo <= v <= hi:
        raise ConversionError(f"{where}: {v} is outside {ptype} ({lo}..{hi})")
    return v


def _check_float(v: Any, where: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ConversionError(f"{where}: {v!r} is not a number")
    return float(v)


def _check_bool(v: Any, where: str) -> bool:
    if isinstance(v, bool):
        return v
    if isinstance(v, int) and v in (0, 1):
        return bool(v)
    raise ConversionError(f"{where}: {v!r} is not a bool")


def _scalar_from_ros(ptype: str, where: str) -> Callable[[Any], Any]:
    if ptype == "bool":
        return lambda v: _check_bool(v, where)
    if ptype in ("float32", "float64"):
        return lambda v: _check_float(v, where)
    return lambda v: _check_int(v, ptype, where)


class Converter:
    """uORB message object <-> genpy message for one uORB message type (nested included)."""

    def __init__(self, mdef: MessageDef, ros_module: ModuleType,
                 registry: MessageRegistry) -> None:
        self.mdef = mdef
        self.ros_cls: type = getattr(ros_module, snake_to_camel(mdef.name))
        assert mdef.cls is not None
        self.uorb_cls: type = mdef.cls
        self._nested: dict[str, Converter] = {}
        for f in mdef.fields:
            if not f.is_primitive:
                self._nested[f.name] = Converter(registry.messages[f.type], ros_module, registry)
        self._ros_slots = tuple(self.ros_cls.__slots__)

    def to_ros(self, msg: Any) -> Any:
        """A genpy message with every field of the uORB message ``msg``."""
        out = self.ros_cls()
        for f in self.mdef.fields:
            v = getattr(msg, f.name)
            if f.is_primitive:
                if f.array and f.type != "char":
                    v = list(v)
                elif f.type == "bool":
                    v = bool(v)
            else:
                conv = self._nested[f.name]
                v = [conv.to_ros(x) for x in v] if f.array else conv.to_ros(v)
            setattr(out, f.name, v)
        return out

    def from_ros(self, ros_msg: Any, where: str = "") -> Any:
        """A uORB message from a genpy one; :class:`ConversionError` if a value does not fit."""
        prefix = where or self.mdef.name
        out = self.uorb_cls()
        for f in self.mdef.fields:
            at = f"{prefix}.{f.name}"
            try:
                v = getattr(ros_msg, f.name)
            except AttributeError:
                raise ConversionError(f"{at}: missing") from None
            if f.is_primitive:
                if f.type == "char":
                    v = self._text(v, f.array or 1, at)
                elif f.array:
                    v = self._array(v, f.array, at, _scalar_from_ros(f.type, at))
                else:
                    v = _scalar_from_ros(f.type, at)(v)
            else:
                conv = self._nested[f.name]
                if f.array:
                    seq = self._array(v, f.array, at, lambda x: x)
                    v = [conv.from_ros(x, f"{at}[{i}]") for i, x in enumerate(seq)]
                else:
                    v = conv.from_ros(v, at)
            setattr(out, f.name, v)
        return out

    @staticmethod
    def _array(v: Any, n: int, at: str, each: Callable[[Any], Any]) -> list[Any]:
        if isinstance(v, (bytes, bytearray)):
            v = list(v)   # genpy gives uint8[N] as bytes
        if not isinstance(v, (list, tuple)):
            raise ConversionError(f"{at}: expected an array of {n}, got {type(v).__name__}")
        if len(v) != n:
            raise ConversionError(f"{at}: expected {n} elements, got {len(v)}")
        return [each(x) for x in v]

    @staticmethod
    def _text(v: Any, n: int, at: str) -> str:
        if isinstance(v, bytes):
            try:
                v = v.decode("utf-8")
            except UnicodeDecodeError:
                raise ConversionError(f"{at}: text is not UTF-8") from None
        if not isinstance(v, str):
            raise ConversionError(f"{at}: expected text, got {type(v).__name__}")
        if "\0" in v:
            raise ConversionError(f"{at}: text holds a NUL character")
        try:
            raw = v.encode("latin-1")
        except UnicodeEncodeError:
            raise ConversionError(f"{at}: text has characters outside Latin-1") from None
        if len(raw) > n:
            raise ConversionError(f"{at}: text of {len(raw)} characters, at most {n}")
        return v


_CONVERTERS: dict[tuple[int, str], Converter] = {}


def converter(topic: str, registry: MessageRegistry | None = None,
              ros_module: ModuleType | None = None) -> Converter:
    """The converter of a uORB topic's type (cached)."""
    reg = registry or default_registry()
    mod = ros_module if ros_module is not None else load()[1]
    mdef = reg.topic(topic)
    key = (id(mod), mdef.name)
    conv = _CONVERTERS.get(key)
    if conv is None:
        conv = _CONVERTERS[key] = Converter(mdef, mod, reg)
    return conv


def main(argv: list[str] | None = None) -> int:
    """``python -m hil.ros.msggen [ROOT]``: generate (if needed) and print the env lines."""
    args = sys.argv[1:] if argv is None else argv
    pkg = ensure_package(args[0] if args else None)
    print(f"# {PACKAGE} in {pkg.package_dir} ({'generated' if pkg.regenerated else 'up to date'}"
          f", {len(list((pkg.package_dir / 'msg').glob('*.msg')))} types)")
    for line in env_lines(pkg):
        print(line)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
