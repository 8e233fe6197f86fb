"""Conditions over observables: a small, explicit grammar (never ``eval``).

A condition is a string ``OBSERVABLE [OP VALUE]`` or a mapping ``{all: [...]}`` /
``{any: [...]}`` / ``{not: ...}`` of conditions:

    nav_state == Return
    motor_us == 900 +- 2          # every motor within 2 us of 900
    motor_us between 900 2000     # every motor in [900, 2000]
    io.flags contains FAILSAFE
    gcs.text contains "Baro Sensor missing"
    armed                         # truthy
    not fmu_alive
    nav_state in [Return, Land]
    topic.sensors_status_imu.failover_count >= 1

``OP`` is one of ``== != < <= > >= in contains between``. A list observable (one value per
motor, per sensor instance) satisfies a comparison when every element does; ``contains`` is
true when one element equals the value or, for text, includes it. Values are numbers,
``true``/``false``/``none``, a quoted string, a bare word (a name such as ``Return``: names
compare case-insensitively) or a ``[list]``. A missing observable (a topic never published, a
dead board) satisfies nothing, not even ``!=``.
"""

from __future__ import annotations

import re
import shlex
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

__all__ = ["Condition", "ConditionError", "parse_condition"]

OPS = ("==", "!=", "<", "<=", ">", ">=", "in", "contains", "between")


class ConditionError(ValueError):
    """A condition that does not parse or names an unknown observable."""


#: a name, an optional element of a nested message array (``esc[1].esc_rpm``), indices
_NAME = re.compile(r"^[A-Za-z_][\w.]*(\[\d+\]\.[A-Za-z_]\w*)?(\[-?\d+(:-?\d*)?\]|\[:-?\d+\])*$")


def _literal(tok: str) -> Any:
    low = tok.lower()
    if low in ("true", "yes"):
        return True
    if low in ("false", "no"):
        return False
    if low in ("none", "null"):
        return None
    try:
        return int(tok, 0)
    except ValueError:
        pass
    try:
        return float(tok)
    except ValueError:
        return tok


def _eq(a: Any, b: Any, tol: float) -> bool:
    if isinstance(a, str) or isinstance(b, str):
        return str(a).lower() == str(b).lower()
    if isinstance(a, bool) or isinstance(b, bool) or a is None or b is None:
        return a == b
    return abs(a - b) <= tol


def _cmp(op: str, a: Any, b: Any, tol: float) -> bool:
    if a is None:
        return False
    try:
        if op == "==":
            return _eq(a, b, tol)
        if op == "!=":
            return not _eq(a, b, tol)
        if op == "<":
            return a < b
        if op == "<=":
            return a <= b
        if op == ">":
            return a > b
        if op == ">=":
            return a >= b
        if op == "in":
            return any(_eq(a, x, tol) for x in b)
        if op == "between":
            return b[0] <= a <= b[1]
    except TypeError:
        return False
    raise ConditionError(f"unknown operator {op!r}")  # pragma: no cover - parse rejects it


@dataclass(frozen=True)
class Condition:
    """A parsed condition; ``text`` is its canonical form for reports."""

    text: str
    test: Callable[[Callable[[str], Any]], bool]
    observables: tuple[str, ...]

    def __call__(self, read: Callable[[str], Any]) -> bool:
        return self.test(read)

    def __str__(self) -> str:
        return self.text


def _parse_atom(text: str, known: Callable[[str], bool]) -> Condition:
    try:
        toks = shlex.split(text, posix=True)
    except ValueError as exc:
        raise ConditionError(f"condition {text!r}: {exc}") from None
    negate = False
    if toks and toks[0] == "not":
        negate = True
        toks = toks[1:]
    if not toks:
        raise ConditionError(f"condition {text!r} is empty")
    name = toks[0]
    if not _NAME.match(name):
        raise ConditionError(f"condition {text!r}: {name!r} is not an observable name")
    if not known(name):
        raise ConditionError(f"condition {text!r}: unknown observable {name!r} "
                             f"(see docs/faults.md, 'Observables')")
    rest = toks[1:]
    if not rest:
        def truthy(read: Callable[[str], Any]) -> bool:
            v = read(name)
            if v is None:
                return False
            ok = bool(v) and (all(v) if isinstance(v, (list, tuple)) else True)
            return ok != negate
        return Condition(text, truthy, (name,))
    op, args = rest[0], rest[1:]
    if op not in OPS:
        raise ConditionError(f"condition {text!r}: unknown operator {op!r} "
                             f"(known: {' '.join(OPS)})")
    tol = 0.0
    if op == "between":
        if len(args) != 2:
            raise ConditionError(f"condition {text!r}: 'between' takes two values (LO HI)")
        value: Any = (_literal(args[0]), _literal(args[1]))
        if not all(isinstance(x, (int, float)) for x in value):
            raise ConditionError(f"condition {text!r}: 'between' needs numbers")
    elif op == "in":
        joined = " ".join(args).strip()
        if not (joined.startswith("[") and joined.endswith("]")):
            raise ConditionError(f"condition {text!r}: 'in' takes a [list]")
        value = [_literal(x.strip().strip("'\"")) for x in joined[1:-1].split(",") if x.strip()]
    else:
        if len(args) == 3 and args[1] == "+-":
            tol_v = _literal(args[2])
            if not isinstance(tol_v, (int, float)) or isinstance(tol_v, bool) or tol_v < 0:
                raise ConditionError(f"condition {text!r}: tolerance must be a number >= 0")
            tol = float(tol_v)
            args = args[:1]
        if len(args) != 1:
            raise ConditionError(f"condition {text!r}: {op!r} takes one value"
                                 f" (quote text with spaces)")
        value = _literal(args[0])
        if op in ("<", "<=", ">", ">=") and (isinstance(value, (str, bool)) or value is None):
            raise ConditionError(f"condition {text!r}: {op!r} needs a number")

    if op == "contains":
        def test(read: Callable[[str], Any]) -> bool:
            v = read(name)
            if v is None:
                return False
            items = v if isinstance(v, (list, tuple)) else [v]
            needle = str(value).lower()
            hit = any(needle in str(x).lower() if isinstance(x, str) else _eq(x, value, 0.0)
                      for x in items)
            return hit != negate
    else:
        def test(read: Callable[[str], Any]) -> bool:
            v = read(name)
            if v is None:
                return False
            if isinstance(v, (list, tuple)):
                ok = bool(v) and all(_cmp(op, x, value, tol) for x in v)
            else:
                ok = _cmp(op, v, value, tol)
            return ok != negate
    return Condition(text, test, (name,))


def parse_condition(spec: Any, known: Callable[[str], bool], where: str = "condition"
                    ) -> Condition:
    """Parse a condition (string or ``all``/``any``/``not`` mapping); errors say ``where``."""
    try:
        if isinstance(spec, bool):
            raise ConditionError(f"{spec!r} is not a condition (quote YAML words like 'yes')")
        if isinstance(spec, str):
            return _parse_atom(spec.strip(), known)
        if isinstance(spec, dict) and len(spec) == 1:
            (key, sub), = spec.items()
            if key in ("all", "any"):
                if not isinstance(sub, list) or not sub:
                    raise ConditionError(f"'{key}' takes a non-empty list of conditions")
                parts = [parse_condition(s, known, f"{where}.{key}[{i}]")
                         for i, s in enumerate(sub)]
                comb = all if key == "all" else any
                text = f" {'and' if key == 'all' else 'or'} ".join(f"({p.text})" for p in parts)
                obs = tuple(o for p in parts for o in p.observables)
                return Condition(text, lambda read: comb(p(read) for p in parts), obs)
            if key == "not":
                inner = parse_condition(sub, known, f"{where}.not")
                return Condition(f"not ({inner.text})", lambda read: not inner(read),
                                 inner.observables)
        raise ConditionError(f"expected a condition string or a mapping with one key all/any/"
                             f"not, got {spec!r}")
    except ConditionError as exc:
        msg = str(exc)
        raise ConditionError(msg if msg.startswith(where) else f"{where}: {msg}") from None
