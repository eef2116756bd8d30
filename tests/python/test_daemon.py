"""lgp.Daemon against a live lgpd."""

import os
import subprocess
import time

import numpy as np
import pytest

import lgp


@pytest.fixture
def daemon(tmp_path):
    exe = os.environ.get("LGPD")
    if not exe:
        pytest.skip("LGPD is not set (CTest sets it where lgpd is built)")
    port_file = tmp_path / "port"
    p = subprocess.Popen([exe, "--data-dir", str(tmp_path / "d"), "--listen", "127.0.0.1:0",
                          "--port-file", str(port_file), "--log-level", "warn",
                          "--front-interval", "0.2"])
    try:
        for _ in range(200):
            if port_file.exists() and port_file.read_text().strip():
                break
            time.sleep(0.05)
        else:
            pytest.fail("lgpd did not start")
        yield lgp.Daemon(f"http://127.0.0.1:{port_file.read_text().strip()}")
    finally:
        p.terminate()
        p.wait(timeout=30)


def test_submit_arrays_wait_and_front(daemon):
    g = np.linspace(0, 1, 12)
    X = np.array([(a, b) for b in g for a in g])
    y = np.exp2(-7 * X[:, 0] - 4 * X[:, 1] ** 2)
    assert daemon.health()["ok"]
    rid = daemon.submit(X=X, y=y, inputs=["x", "y"], outputs=["f"], name="python",
                        search={"generations": 30, "threads": 1, "seed": 2},
                        program={"ops": ["add", "mul", "mad", "square", "exp2"]})
    s = daemon.wait(rid, poll=0.2, timeout=120)
    assert s["status"] == "finished", s
    front = daemon.front(rid)
    assert front.outputs == ["f"] and len(front) > 0
    # The daemon's front predicts like the engine scored it.
    m = front.best()
    rmse = float(np.sqrt(np.mean((m.predict(X) - y) ** 2)))
    assert rmse == pytest.approx(m.metrics["f"]["rmse"], rel=1e-5, abs=1e-9)
    assert any(r["id"] == rid for r in daemon.runs())
    assert daemon.delete(rid)["deleted"]


def test_refusals_raise_with_the_field(daemon):
    X = np.zeros((10, 1))
    with pytest.raises(lgp.DaemonError) as e:
        daemon.submit(X=X, y=np.zeros(10), search={"population": 2, "generations": 3})
    assert e.value.status == 400 and e.value.field == "/search/population"
    with pytest.raises(lgp.DaemonError) as e:
        daemon.status("0123456789abcdef")
    assert e.value.status == 404
    with pytest.raises(ConnectionError):
        lgp.Daemon("http://127.0.0.1:9", timeout=2).health()
