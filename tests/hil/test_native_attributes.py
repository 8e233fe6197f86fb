"""A class attribute of an ordinary (pure Python) subclass does not override an attribute that a
compiled base class declares: compiled code reads the base's own slot, so the subclass's value
is seen by the pure tier only and the two tiers model different things (the GPS driver ran for
free compiled until its ``cpu_cost_ns`` moved to the instance; the FM25V01 took any SCK). This
checks, without building, that no ordinary board class does it."""

from __future__ import annotations

import ast
import importlib
import inspect
import pkgutil
from types import ModuleType

from hil import native

_FAST = {rel[:-3].replace("/", ".") for rel in native.FAST_MODULES}


def _instance_attributes(cls: type) -> set[str]:
    """What a compiled class declares per instance: class-body annotations that are not
    ClassVar, and every ``self.x = ...`` in its methods."""
    module = inspect.getmodule(cls)
    assert module is not None
    names: set[str] = set()
    for node in ast.walk(ast.parse(inspect.getsource(module))):
        if not (isinstance(node, ast.ClassDef) and node.name == cls.__name__):
            continue
        for stmt in node.body:
            if (isinstance(stmt, ast.AnnAssign) and isinstance(stmt.target, ast.Name)
                    and "ClassVar" not in ast.unparse(stmt.annotation)):
                names.add(stmt.target.id)
        for sub in ast.walk(node):
            targets = (sub.targets if isinstance(sub, ast.Assign)
                       else [sub.target] if isinstance(sub, ast.AnnAssign) else [])
            for target in targets:
                for e in ast.walk(target):
                    if (isinstance(e, ast.Attribute) and isinstance(e.value, ast.Name)
                            and e.value.id == "self"):
                        names.add(e.attr)
    return names


def _board_modules() -> list[ModuleType]:
    out = []
    for pkg in native.PACKAGES:
        root = importlib.import_module(pkg)
        for info in pkgutil.walk_packages(root.__path__, pkg + "."):
            out.append(importlib.import_module(info.name))
    return out


def test_ordinary_classes_override_no_compiled_attribute() -> None:
    declared: dict[type, set[str]] = {}
    found = []
    checked = 0
    for module in _board_modules():
        if module.__name__ in _FAST:
            continue
        for cls in vars(module).values():
            if not inspect.isclass(cls) or cls.__module__ != module.__name__:
                continue
            for base in cls.__mro__[1:]:
                if base.__module__ not in _FAST:
                    continue
                checked += 1
                if base not in declared:
                    declared[base] = _instance_attributes(base)
                for name, value in vars(cls).items():
                    if name in declared[base] and not callable(value) \
                            and not isinstance(value, (property, staticmethod, classmethod)):
                        found.append(f"{module.__name__}.{cls.__name__}.{name} (declared by "
                                     f"compiled {base.__module__}.{base.__name__}): set it on "
                                     "the instance")
    assert checked > 20  # drivers and modules extend WorkItem, models SpiTarget/I2cTarget
    assert not found, "\n".join(sorted(set(found)))
