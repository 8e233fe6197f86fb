"""Fuzzing the scenario loader: any file is a Scenario or a ScenarioError, nothing else."""

from __future__ import annotations

import math
from pathlib import Path

import yaml
from hypothesis import given
from hypothesis import strategies as st

from hil.scenarios import Scenario, ScenarioError, load_scenario
from hil.scenarios.model import (EXPECT_KINDS, GCS_COMMANDS, INITIAL_KEYS, PILOT_ACTIONS,
                                 STEP_KINDS, TOP_KEYS)
from tests.fuzzing import fuzz

LIBRARY = sorted((Path(__file__).resolve().parents[2] / "hil" / "scenarios" / "library")
                 .glob("*.yaml"))
LIBRARY_TEXT = [p.read_bytes() for p in LIBRARY]

#: every key the format knows, so random documents reach the checks behind them
KEYS = sorted(TOP_KEYS | INITIAL_KEYS | set(STEP_KINDS) | set(PILOT_ACTIONS) | set(GCS_COMMANDS)
              | set(EXPECT_KINDS) | {"at", "name", "kind", "target", "params", "duration",
                                     "until", "within", "that", "of", "from", "after", "for",
                                     "ramp", "run", "may_fail", "alt", "all", "any", "not",
                                     "roll", "pitch", "yaw", "throttle", "NAV_RCL_ACT",
                                     "MPC_XY_VEL_MAX", "rc.tx_off", "gps.jump", "north_m"})
SCALARS = st.one_of(
    st.none(), st.booleans(), st.integers(), st.integers(min_value=-2 ** 80, max_value=2 ** 80),
    st.floats(), st.sampled_from([math.nan, math.inf, -math.inf, 1e39, -1e39, 1e400 * 0]),
    st.text(max_size=12), st.sampled_from(["armed", "nav_state == Return", "sbus", "rc.tx_off",
                                           "position", "alt_agl_m > 3", "hover", "1e39",
                                           "param show", "ver\nreboot", "echo " + "x" * 123]))
TREES = st.recursive(
    SCALARS,
    lambda kids: st.one_of(st.lists(kids, max_size=4),
                           st.dictionaries(st.one_of(st.sampled_from(KEYS), SCALARS), kids,
                                           max_size=4)),
    max_leaves=30)


def _mutate(data: bytes, draw: st.DrawFn) -> bytes:
    """Bit flips, a truncation and a splice of another library file."""
    buf = bytearray(data)
    for _ in range(draw(st.integers(0, 4))):
        if buf:
            i = draw(st.integers(0, len(buf) - 1))
            buf[i] ^= 1 << draw(st.integers(0, 7))
    if draw(st.booleans()) and buf:
        buf = buf[:draw(st.integers(0, len(buf)))]
    if draw(st.booleans()):
        other = draw(st.sampled_from(LIBRARY_TEXT))
        at, frm = draw(st.integers(0, len(buf))), draw(st.integers(0, len(other)))
        buf = buf[:at] + other[frm:]
    return bytes(buf)


@st.composite
def documents(draw: st.DrawFn) -> bytes:
    how = draw(st.sampled_from(["tree", "library-tree", "mutated", "text", "nested"]))
    if how == "tree":
        return yaml.safe_dump(draw(TREES)).encode()
    if how == "library-tree":  # a real scenario with one value swapped for a random one
        doc = yaml.safe_load(draw(st.sampled_from(LIBRARY_TEXT)))
        node = doc
        key = draw(st.sampled_from(sorted(node, key=str)))
        for _ in range(draw(st.integers(0, 3))):
            child = node[key]
            if not isinstance(child, (dict, list)) or not child:
                break
            node = child
            key = draw(st.sampled_from(sorted(node, key=str)) if isinstance(node, dict) else
                       st.integers(0, len(node) - 1))
        node[key] = draw(TREES)
        return yaml.safe_dump(doc).encode()
    if how == "mutated":
        return _mutate(draw(st.sampled_from(LIBRARY_TEXT)), draw)
    if how == "nested":  # deep flow collections and alias chains
        depth = draw(st.integers(1, 4000))
        return draw(st.sampled_from([b"name: " + b"[" * depth + b"]" * depth,
                                     b"events: {e: " + b"{not: " * depth + b"armed" +
                                     b"}" * depth + b"}\nexpect: [{never: armed}]",
                                     b"a: &a [x]\n" + b"".join(
                                         b"a%d: &a%d [*a%s, *a%s]\n" % (
                                             i, i, b"" if i == 0 else b"%d" % (i - 1),
                                             b"" if i == 0 else b"%d" % (i - 1))
                                         for i in range(min(depth, 60)))]))
    return draw(st.binary(max_size=300)) if draw(st.booleans()) else \
        draw(st.text(max_size=300)).encode("utf-8", "surrogatepass")


@fuzz(examples=100)
@given(documents())
def test_any_file_is_a_scenario_or_a_scenario_error(tmp_path_factory, text):
    """Invariant: load_scenario on any bytes returns a Scenario whose times are finite or
    raises ScenarioError naming the file, never another exception, and terminates."""
    path = tmp_path_factory.getbasetemp() / "fuzzed.yaml"
    path.write_bytes(text)
    try:
        sc = load_scenario(str(path))
    except ScenarioError as exc:
        assert str(exc).startswith(f"{path}: ")
        return
    assert isinstance(sc, Scenario)
    assert math.isfinite(sc.duration_s) and 1.0 <= sc.sample_ms <= 1000.0
    assert all(s.at_s is None or math.isfinite(s.at_s) for s in sc.timeline)
    assert all(e.window_s is None or math.isfinite(e.window_s) for e in sc.expect)
