"""lgp.Daemon against a live lgpd."""

import os
import socket
import subprocess
import threading
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


class _RawServer:
    """A one-shot HTTP server on loopback that answers every connection with `serve(conn)`:
    a hostile or broken daemon, byte for byte."""

    def __init__(self, serve):
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(4)
        self.url = f"http://127.0.0.1:{self.sock.getsockname()[1]}"
        self._serve = serve
        self._thread = threading.Thread(target=self._loop, daemon=True)
        self._thread.start()

    def _loop(self):
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            with conn:
                conn.recv(65536)
                try:
                    self._serve(conn)
                except OSError:
                    pass  # the client hung up, as it should

    def close(self):
        self.sock.close()


def _trickle(conn):
    # Headers, then one byte of a 1000-byte body every 0.1 s, for at most 30 s.
    conn.sendall(b"HTTP/1.1 200 OK\r\nContent-Type: application/json\r\n"
                 b"Content-Length: 1000\r\n\r\n")
    for _ in range(300):
        conn.sendall(b" ")
        time.sleep(0.1)


def _huge(status):
    def serve(conn):
        size = 400 << 20
        conn.sendall(f"HTTP/1.1 {status}\r\nContent-Type: application/json\r\n"
                     f"Content-Length: {size}\r\n\r\n".encode())
        chunk = b"x" * (1 << 20)
        for _ in range(size >> 20):
            conn.sendall(chunk)
    return serve


def test_a_trickling_server_cannot_hold_a_call():
    # Each byte came within the socket timeout, so the call went on for the whole body and
    # ended in a raw IncompleteRead (hardening round 3, F10). The timeout is the whole call's.
    server = _RawServer(_trickle)
    try:
        with pytest.raises(ConnectionError, match="no complete answer within 1 s"):
            lgp.Daemon(server.url, timeout=1).health()
    finally:
        server.close()


def test_a_huge_answer_is_refused_not_buffered():
    server = _RawServer(_huge("200 OK"))
    try:
        with pytest.raises(ConnectionError, match=r"more than max_response_bytes \(1048576\)"):
            lgp.Daemon(server.url, timeout=30, max_response_bytes=1 << 20).runs()
    finally:
        server.close()


def test_a_huge_error_body_is_cut_short():
    # A 400 MiB error body was read whole and copied into the exception.
    server = _RawServer(_huge("500 Internal Server Error"))
    try:
        with pytest.raises(lgp.DaemonError) as e:
            lgp.Daemon(server.url, timeout=30).runs()
        assert e.value.status == 500
        assert len(str(e.value)) < 4096
    finally:
        server.close()


def test_a_body_cut_short_is_a_connection_error():
    def short(conn):
        conn.sendall(b"HTTP/1.1 200 OK\r\nContent-Length: 100\r\n\r\n{\"runs\": [")
    server = _RawServer(short)
    try:
        with pytest.raises(ConnectionError, match="ended after 10 of its 100 bytes"):
            lgp.Daemon(server.url, timeout=10).runs()
    finally:
        server.close()
