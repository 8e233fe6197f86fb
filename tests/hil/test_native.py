"""The compiled tier (hil.native): freshness rules, and the same bytes as the pure modules.

The equivalence tests need a compiled tier: the user's if it is fresh (`make native`), else
one built here into a temporary folder at gcc -O0 (quicker than -O3; the
equivalence is about what mypyc makes of the source, not gcc's optimiser), never a skip. One
test function uses it, so that under xdist one worker builds it while the other runs the rest
of the suite (pytest-xdist 3.8's ``--dist loadgroup`` does not group under pytest 9, whose
node ids it no longer rewrites: two tests needing the tier could land on both workers and
build it twice).
"""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from hil import native


def _compiled_tier(tmp: Path) -> Path:
    """A compiled tier of the current sources: the user's when fresh, else a quick one."""
    if native.status()[0] == "fresh":
        return native.native_dir()
    d = native.build(dest=tmp / "tier", opt_level="0")
    assert (d / "manifest.json").exists()
    return d


def _tree(root: Path) -> None:
    for pkg in native.PACKAGES:
        (root / pkg).mkdir(parents=True)
        (root / pkg / "__init__.py").write_text("")
    (root / "board" / "kernel.py").write_text("X = 1\n")


def test_status_absent_then_stale_on_any_source_edit(tmp_path: Path) -> None:
    _tree(tmp_path)
    state, why = native.status(tmp_path)
    assert state == "absent" and "hil native build" in why
    d = native.native_dir(tmp_path)
    d.mkdir(parents=True)
    (d / "manifest.json").write_text(json.dumps({"digest": native._digest(tmp_path)}))
    assert native.status(tmp_path)[0] == "fresh"
    (tmp_path / "board" / "kernel.py").write_text("X = 2\n")  # an edit: the tier is stale
    state, why = native.status(tmp_path)
    assert state == "stale" and "changed" in why
    (d / "manifest.json").write_text("{not json")
    assert native.status(tmp_path)[0] == "stale"


def test_activate_refuses_stale_and_respects_hil_pure(tmp_path: Path, monkeypatch,
                                                      capsys) -> None:
    _tree(tmp_path)
    d = native.native_dir(tmp_path)
    d.mkdir(parents=True)
    (d / "manifest.json").write_text(json.dumps({"digest": "0" * 64}))
    path_before = list(sys.path)
    assert native.activate(tmp_path) is False
    assert "pure Python modules" in capsys.readouterr().err
    (d / "manifest.json").write_text(json.dumps({"digest": native._digest(tmp_path)}))
    monkeypatch.setenv("HIL_PURE", "1")
    assert native.activate(tmp_path) is False
    monkeypatch.delenv("HIL_PURE")
    # In this process the pure board package is already imported: too late, and it says so.
    import board  # noqa: F401

    assert native.activate(tmp_path) is False
    assert "imported before" in capsys.readouterr().err
    assert sys.path == path_before


def test_compiled_list_covers_the_hot_path() -> None:
    for hot in ("board/kernel.py", "board/spi.py", "peripherals/mpu6000/sampling.py",
                "firmware/platform/uorb.py", "firmware/platform/workqueue.py",
                "firmware/drivers/imu/mpu6000.py", "ioproc/firmware/mixer_tick.py"):
        assert hot in native.COMPILED


def _classes_and_bases(rel: str) -> list[tuple[str, list[tuple[str, str]], bool]]:
    """Each class of a board module: its name, its bases as (module file, class name) where
    they come from the board packages, and whether it allows interpreted subclasses."""
    tree = ast.parse((native.ROOT / rel).read_text())
    imported: dict[str, tuple[str, str]] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            mod = node.module or ""
            if node.level:
                mod = ".".join(rel[:-3].split("/")[:-node.level] + ([mod] if mod else []))
            for alias in node.names:
                imported[alias.asname or alias.name] = (mod.replace(".", "/") + ".py", alias.name)
    local = {n.name for n in ast.walk(tree) if isinstance(n, ast.ClassDef)}
    out = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.ClassDef):
            continue
        bases = [imported[b.id] if b.id in imported else (rel, b.id)
                 for b in node.bases if isinstance(b, ast.Name)
                 and (b.id in imported or b.id in local)]
        bases = [(f, c) for f, c in bases if (native.ROOT / f).exists()]
        # a non-native class (``native_class=False``: the exceptions) is an ordinary Python
        # class even when compiled, so any module may subclass it
        decorators = ast.unparse(node.decorator_list) if node.decorator_list else ""
        allows = "allow_interpreted_subclasses" in decorators or "native_class=False" in decorators
        out.append((node.name, bases, allows))
    return out


def test_fast_modules_compile_as_a_closed_set() -> None:
    """What mypyc needs of the fast-module list, checked without building: a compiled class's
    bases are compiled (mypyc cannot extend a Python class), and a compiled class that an
    ordinary module subclasses allows it (else importing that module raises TypeError)."""
    compiled = set(native.COMPILED)
    allows: dict[tuple[str, str], bool] = {}
    every = sorted(p.relative_to(native.ROOT).as_posix() for pkg in native.PACKAGES
                   for p in (native.ROOT / pkg).rglob("*.py") if "__pycache__" not in p.parts)
    assert compiled <= set(every), compiled - set(every)
    table = {rel: _classes_and_bases(rel) for rel in every}
    for rel, classes in table.items():
        for name, _bases, allow in classes:
            allows[(rel, name)] = allow
    for rel in sorted(compiled):
        for name, bases, _ in table[rel]:
            for base in bases:
                assert base[0] in compiled, f"{rel}: {name} extends {base}, which is not compiled"
    for rel in every:
        if rel in compiled:
            continue
        for name, bases, _ in table[rel]:
            for base in bases:
                if base[0] in compiled:
                    assert allows.get(base, False), \
                        f"{rel}: {name} extends compiled {base[1]} ({base[0]}), which lacks " \
                        "@mypyc_attr(allow_interpreted_subclasses=True)"


def _child_env(extra: dict[str, str]) -> dict[str, str]:
    """This environment without a tier choice, then ``extra`` (which tier the child imports)."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "HIL_PURE")}
    return {**env, **extra}


def _check(tmp: Path, name: str, env_extra: dict[str, str], seconds: float) -> dict:
    out = subprocess.run([sys.executable, "-m", "hil.native", str(tmp / name), str(seconds)],
                         cwd=tmp, env=_child_env(env_extra), capture_output=True, text=True,
                         timeout=900, check=False)
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.slow  # builds a quick tier: started first (tests/conftest.py)
def test_compiled_and_pure_agree(tmp_path: Path) -> None:
    """Ten virtual seconds of the whole system (drivers, sensors, estimator, controllers,
    px4io and the IO, logger with the raw sensors), compiled and pure: same log bytes; and
    the DSM decoder's frames (:func:`_dsm_frames_agree`)."""
    compiled_tier = _compiled_tier(tmp_path)
    _dsm_frames_agree(tmp_path, compiled_tier)
    compiled = _check(tmp_path, "compiled", {"PYTHONPATH": str(compiled_tier)}, 10.0)
    pure = _check(tmp_path, "pure", {}, 10.0)
    assert compiled["compiled"] is True and not compiled["kernel"].endswith(".py")
    assert pure["compiled"] is False and pure["kernel"].endswith(".py")
    assert compiled["logs"] and compiled["log_bytes"][0] > 100_000
    assert compiled["logs"] == pure["logs"]


@pytest.mark.parametrize("argv", [["native", "status"], ["native", "bogus"]])
def test_cli_native_commands(argv: list[str], capsys) -> None:
    from hil.cli import main

    if argv[1] == "bogus":
        with pytest.raises(SystemExit):
            main(argv)
        assert "invalid choice" in capsys.readouterr().err
        return
    rc = main(argv)
    out = capsys.readouterr().out
    assert out.split(":")[0] in ("fresh", "stale", "absent")
    assert rc == (0 if out.startswith("fresh") else 1)


# Decodes DSM streams (11-bit and 10-bit resolution guesses, a 150 ms fade, a corrupt frame)
# and prints what the decoder output, as one JSON line; run compiled and pure, it must agree.
_DSM_SCRIPT = """
import json
import ioproc.rc.dsm
from ioproc.rc.dsm import DsmDecoder, dsm_word, encode_dsm_frame

print(ioproc.rc.dsm.__file__)

out = []
for bits in (11, 10):
    dec = DsmDecoder()
    t = 0
    for k in range(60):
        t += 11_000
        if 20 <= k < 34:
            continue  # a fade: no frames for ~150 ms
        pos = (300 + 7 * k) % (1 << bits)
        words = [dsm_word(c, (pos + 40 * c) % (1 << bits), bits=bits) for c in range(7)]
        frame = bytearray(encode_dsm_frame(words))
        if k == 45:
            frame[4] ^= 0x7C  # a corrupt channel ID
        got = [dec.feed_byte(t + 87 * i, b) for i, b in enumerate(frame)]
        out.append([any(got), dec.mode, dec.frames, dec.frame_errors, list(dec.channels)])
print(json.dumps(out))
"""


def _dsm_frames_agree(tmp_path: Path, compiled_tier: Path) -> None:
    """The DSM decoder compiled gives the pure decoder's frames: mypyc once compiled a
    narrowed ``self.mode is None`` check into a TypeError on the frame that ends the guess."""
    assert "ioproc/rc/dsm.py" in native.COMPILED
    runs = {}
    for name, extra in (("compiled", {"PYTHONPATH": str(compiled_tier)}),
                        ("pure", {"PYTHONPATH": str(native.ROOT)})):
        res = subprocess.run([sys.executable, "-c", _DSM_SCRIPT], cwd=tmp_path,
                             env=_child_env(extra), capture_output=True, text=True, timeout=300,
                             check=False)
        assert res.returncode == 0, res.stderr[-3000:]
        where, line = res.stdout.strip().splitlines()[-2:]
        assert where.endswith(".py") == (name == "pure"), where
        runs[name] = json.loads(line)
    assert runs["compiled"] == runs["pure"]
    assert sum(r[0] for r in runs["pure"]) >= 30  # frames came out, in both resolutions
    assert {r[1] for r in runs["pure"]} >= {10, 11}
