"""A ROS 1 master for the tests of the ROS edge (hil/ros/): Debian's ``roscore`` on a free port.

``roscore`` (session scope) starts ``roscore -p PORT`` on 127.0.0.1 in a process group of its
own, with ``ROS_HOME`` (logs, the master's run id) in a temporary folder, waits until the master
answers over XML-RPC, exports ``ROS_MASTER_URI``/``ROS_IP``/``ROS_HOME`` to this process (so
rospy in the test process and every subprocess reach it) and yields the master's URI. At the end
the whole group (master, rosout) is stopped: SIGINT as a user's Ctrl-C, SIGKILL if it lingers.

ROS missing is a failure, not a skip: ``make test`` installs it (Makefile target ``ros``), so a
machine without ``roscore`` is a broken set-up, said as such. ``ros_env`` is the environment
for subprocesses (``rostopic``, ``hil fly --ros``, a user's rospy script).
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import tempfile
import time
import xmlrpc.client
from typing import Iterator

import pytest

#: how long roscore may take to answer (it starts in ~1-2 s here; a loaded machine is slower)
START_TIMEOUT_S = 30.0
_ROS_VARS = ("ROS_MASTER_URI", "ROS_IP", "ROS_HOME", "ROS_LOG_DIR", "ROS_HOSTNAME")


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _master_up(uri: str) -> bool:
    try:
        code, _msg, _pid = xmlrpc.client.ServerProxy(uri).getPid("/fmu_hil_test")
        return code == 1
    except (OSError, xmlrpc.client.Error):
        return False


def _stop_group(proc: subprocess.Popen) -> None:
    """Stop roscore and its children (rosmaster, rosout): one process group, started by us."""
    if proc.poll() is not None:
        return
    try:
        os.killpg(proc.pid, signal.SIGINT)
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
    except ProcessLookupError:
        pass
    try:  # a child that outlived roscore itself (same group)
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass


@pytest.fixture(scope="session")
def roscore() -> Iterator[str]:
    """A running ROS master (``http://127.0.0.1:PORT``), exported as ``ROS_MASTER_URI``."""
    exe = shutil.which("roscore")
    if exe is None:
        pytest.fail("ROS 1 is not installed: no `roscore` on PATH. `make ros` (as root) installs "
                    "Debian's ros-core, python3-rospy and the message packages; `make test` runs "
                    "it first (README, Set-up).", pytrace=False)
    home = tempfile.mkdtemp(prefix="fmu-hil-ros-")
    port = _free_port()
    uri = f"http://127.0.0.1:{port}"
    saved = {k: os.environ.get(k) for k in _ROS_VARS}
    env = {**os.environ, "ROS_MASTER_URI": uri, "ROS_IP": "127.0.0.1", "ROS_HOME": home,
           "ROS_LOG_DIR": os.path.join(home, "log")}
    env.pop("ROS_HOSTNAME", None)  # ROS_IP is what nodes advertise
    log = open(os.path.join(home, "roscore.out"), "wb")
    proc = subprocess.Popen([exe, "-p", str(port)], env=env, stdout=log,
                            stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                            start_new_session=True)
    try:
        deadline = time.monotonic() + START_TIMEOUT_S
        while not _master_up(uri):
            if proc.poll() is not None or time.monotonic() > deadline:
                log.flush()
                with open(os.path.join(home, "roscore.out"), "rb") as f:
                    tail = f.read()[-2000:].decode(errors="replace")
                pytest.fail(f"roscore -p {port} did not come up (exit {proc.poll()}):\n{tail}",
                            pytrace=False)
            time.sleep(0.1)
        for k in _ROS_VARS:
            if k in env:
                os.environ[k] = env[k]
            else:
                os.environ.pop(k, None)
        yield uri
    finally:
        _stop_group(proc)
        log.close()
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
        shutil.rmtree(home, ignore_errors=True)


@pytest.fixture
def ros_env(roscore: str) -> dict[str, str]:
    """The environment for a ROS subprocess (rostopic, hil fly --ros, a rospy script): this
    process's, with the master's variables. Not PYTHONPATH: entries there come before the
    venv's own packages, so a venv script appends Debian's dist-packages to ``sys.path``
    itself (hil.ros does), and Debian's ``rostopic`` runs on /usr/bin/python3, which has it."""
    return dict(os.environ)
