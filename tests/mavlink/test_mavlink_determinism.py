"""Same inputs, same bytes: a GCS session is reproducible in virtual time."""

from tests.mavlink.conftest import open_session


def _run(root):
    s = open_session(root)
    try:
        s.gcs.wait_heartbeat()
        s.gcs.param_list()
        s.gcs.shell("ver hw")
        s.gcs.step(0.5)
        return [(t, bytes(m.get_msgbuf())) for t, m in s.gcs.log]
    finally:
        s.close()


def test_two_runs_identical(tmp_path):
    a = _run(tmp_path / "a")
    b = _run(tmp_path / "b")
    assert len(a) > 400 and a == b
