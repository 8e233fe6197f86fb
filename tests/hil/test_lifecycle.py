"""Process hygiene of `hil`: Ctrl-C (SIGINT) leaves no board process behind."""

import os
import signal
import subprocess
import sys
import time


def _children(pid):
    kids = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
        except (FileNotFoundError, ProcessLookupError):
            continue
        if int(fields[1]) == pid and fields[0] != "Z":
            kids.append(int(entry))
    return kids


def _alive(pid):
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def test_sigint_to_hil_run_leaves_no_orphans(tmp_path):
    # Started with SIGINT ignored, as a script's `hil run &` is: hil run takes it back.
    proc = subprocess.Popen([sys.executable, "-m", "hil.cli", "run", "--out", str(tmp_path)],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    try:
        line = proc.stdout.readline()
        # Wait until the lockstep is running (the first phase line) and the boards exist; the
        # progress lines before it say what the run is doing.
        seen = [line]
        while "booted" not in line:
            line = proc.stdout.readline()
            assert line, "".join(seen)
            seen.append(line)
        assert any("hil run" in s for s in seen), "".join(seen)  # (after any native notice)
        assert any("booting" in s for s in seen), "".join(seen)
        boards = [p for p in _children(proc.pid) if _alive(p)]
        assert len(boards) >= 2  # the FMU and IO board processes (plus maybe a tracker)
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, out
    deadline = time.monotonic() + 5
    while any(_alive(p) for p in boards) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not [p for p in boards if _alive(p)]


def test_sigint_stops_hil_fly_started_with_sigint_ignored(tmp_path):
    """`hil fly &` from a script inherits SIGINT as ignored; `kill -INT` must still stop it."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "hil.cli", "fly", "--out", str(tmp_path), "--duration", "600"],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    try:
        seen = []
        line = proc.stdout.readline()
        while "Ctrl-C to stop" not in line:  # the banner's last line: the boards are running
            assert line, "".join(seen)
            seen.append(line)
            line = proc.stdout.readline()
        with open(f"/proc/{proc.pid}/status") as f:
            ignored = int(next(x for x in f if x.startswith("SigIgn:")).split()[1], 16)
        assert not ignored & (1 << (signal.SIGINT - 1))  # hil fly took SIGINT back
        boards = [p for p in _children(proc.pid) if _alive(p)]
        assert len(boards) >= 2  # the FMU and IO board processes
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, out
    assert "hil fly: stopped" in out
    deadline = time.monotonic() + 5
    while any(_alive(p) for p in boards) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not [p for p in boards if _alive(p)]
