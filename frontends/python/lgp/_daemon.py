"""lgp.Daemon: a client of lgpd's HTTP API (frontends/lgpd/README.md), standard library only."""

import http.client
import io
import json
import time
import urllib.parse


from . import _config
from ._fit import Table, _arrays
from ._front import Front

_ENDED = ("finished", "failed", "cancelled")
# What an error answer may add to DaemonError's message (the rest of its body is not read).
_ERROR_BODY_BYTES = 64 << 10


class DaemonError(ValueError):
    """A request lgpd refused: ``status`` is the HTTP status, ``field`` the config field it
    names (for a 400), else None."""

    def __init__(self, message, status, field=None):
        super().__init__(message)
        self.status = status
        self.field = field


class _DeadlineRaw(io.RawIOBase):
    """A socket's input that ends in TimeoutError at the request's deadline: each read waits
    at most what is left, so a server that trickles a byte at a time cannot hold a call."""

    def __init__(self, sock, deadline):
        super().__init__()
        self._sock, self._deadline = sock, deadline

    def readable(self):
        return True

    def readinto(self, b):
        left = self._deadline - time.monotonic()
        if left <= 0:
            raise TimeoutError("no complete answer within the deadline")
        self._sock.settimeout(left)
        return self._sock.recv_into(b)


class _DeadlineSocket:
    """The connection's socket as http.client uses it, with every wait bounded by the
    deadline."""

    def __init__(self, sock, deadline):
        self._sock, self._deadline = sock, deadline

    def makefile(self, mode="r", *args, **kwargs):
        return io.BufferedReader(_DeadlineRaw(self._sock, self._deadline))

    def sendall(self, data, *args):
        left = self._deadline - time.monotonic()
        if left <= 0:
            raise TimeoutError("no complete answer within the deadline")
        self._sock.settimeout(left)
        return self._sock.sendall(data, *args)

    def __getattr__(self, name):
        return getattr(self._sock, name)


class Daemon:
    """A connection to a running lgpd, e.g. ``Daemon("http://127.0.0.1:8737", token=...)``.

    ``submit`` queues a run and returns its id; ``status``, ``wait``, ``front``, ``cancel``,
    ``delete`` and ``runs`` follow the HTTP API. Refusals raise :class:`DaemonError` (a
    ValueError) with lgpd's message; an unreachable daemon, one that does not answer within
    ``timeout`` seconds (the whole request: connecting, sending, the answer's last byte), or
    an answer larger than ``max_response_bytes`` raises ConnectionError.
    """

    def __init__(self, url="http://127.0.0.1:8737", token=None, timeout=30.0,
                 max_response_bytes=256 << 20):
        if not isinstance(url, str) or not url.startswith(("http://", "https://")):
            raise ValueError(f"url: must start with http:// or https:// (got {url!r})")
        if isinstance(timeout, bool) or not isinstance(timeout, (int, float)) or \
                not 0 < timeout < float("inf"):
            raise ValueError(f"timeout: must be a number of seconds > 0 (got {timeout!r})")
        if isinstance(max_response_bytes, bool) or not isinstance(max_response_bytes, int) or \
                max_response_bytes < 1:
            raise ValueError(f"max_response_bytes: must be an integer >= 1 "
                             f"(got {max_response_bytes!r})")
        self.url = url.rstrip("/")
        self.token = token
        self.timeout = timeout
        self.max_response_bytes = max_response_bytes

    def _request(self, method, path, body=None):
        headers = {"Accept": "application/json"}
        data = None
        if body is not None:
            data = _config.dumps(body).encode()
            headers["Content-Type"] = "application/json"
        if self.token:
            headers["Authorization"] = f"Bearer {self.token}"
        where = f"lgpd at {self.url}: {method} {path}"
        parts = urllib.parse.urlsplit(self.url)
        try:
            port = parts.port
        except ValueError:
            raise ValueError(f"url: bad port in {self.url!r}") from None
        make = http.client.HTTPSConnection if parts.scheme == "https" else \
            http.client.HTTPConnection
        deadline = time.monotonic() + self.timeout
        conn = make(parts.hostname, port, timeout=self.timeout)
        try:
            conn.connect()
            conn.sock = _DeadlineSocket(conn.sock, deadline)
            conn.request(method, parts.path + path, body=data, headers=headers)
            r = conn.getresponse()
            ok = 200 <= r.status < 300
            status, reason = r.status, r.reason
            text = self._read(r, self.max_response_bytes if ok else _ERROR_BODY_BYTES, where, ok)
        except TimeoutError:
            raise ConnectionError(f"{where}: no complete answer within {self.timeout:g} s "
                                  "(the Daemon's timeout)") from None
        except (OSError, http.client.HTTPException) as e:
            raise ConnectionError(f"{where}: {e.__class__.__name__}: {e}"[:500]) from None
        finally:
            conn.close()
        if not ok:
            try:
                doc = json.loads(text)
                msg, field = doc.get("error", text), doc.get("field")
                if not isinstance(field, str):
                    field = None
            except (ValueError, RecursionError, AttributeError):
                msg, field = text.strip() or reason, None
            raise DaemonError(f"lgpd: {method} {path}: {status}: {str(msg)[:2000]}", status, field)
        try:
            return json.loads(text)
        except (ValueError, RecursionError):
            raise DaemonError(f"lgpd: {method} {path}: {status}: the answer is not JSON",
                              status) from None

    @staticmethod
    def _read(r, limit, where, whole):
        """The body, read up to ``limit`` bytes. Past it, a success is a ConnectionError (it
        would be cut) and an error's message is cut short; a body that ends before its
        Content-Length is a ConnectionError."""
        length = r.getheader("Content-Length")
        length = int(length) if length is not None and length.isdigit() else None
        if whole and length is not None and length > limit:
            raise ConnectionError(f"{where}: an answer of {length} bytes, more than "
                                  f"max_response_bytes ({limit})")
        chunks, size = [], 0
        while size <= limit:
            chunk = r.read1(min(1 << 20, limit + 1 - size))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
        if whole and size > limit:
            raise ConnectionError(f"{where}: an answer larger than max_response_bytes ({limit})")
        if whole and length is not None and size < length:
            raise ConnectionError(f"{where}: the answer ended after {size} of its {length} bytes")
        return b"".join(chunks)[:limit].decode(errors="replace")

    def health(self):
        """The daemon's health document ({"ok": true, ...})."""
        return self._request("GET", "/api/v1/health")

    def submit(self, config=None, X=None, y=None, *, inputs=None, outputs=None, name=None,
               **sections):
        """Queues a run; returns its id.

        ``config`` is a run config (dict or JSON file) whose data paths lgpd can read, or give
        the data as arrays (``X``, ``y``, or a :class:`lgp.Table` as ``X``): they are sent as an
        inline table. Keyword sections (``search={...}``, ...) are merged into the config.
        """
        cfg, _ = _config.build(config, sections)
        if isinstance(X, Table):
            X, y, inputs, outputs = X.X, X.y, inputs or X.inputs, outputs or X.outputs
        if X is not None:
            Xa, ya, inputs, outputs = _arrays(X, y, inputs, outputs)
            columns = {n: Xa[:, i].tolist() for i, n in enumerate(inputs)}
            columns.update({n: ya[:, i].tolist() for i, n in enumerate(outputs)})
            data = cfg.setdefault("data", {})
            for k in ("path", "scene"):
                data.pop(k, None)
            data["table"] = {"format": "lgp-table/1", "inputs": inputs, "outputs": outputs,
                             "columns": columns}
            data["inputs"], data["outputs"] = inputs, outputs
        if name is not None:
            cfg["name"] = str(name)
        return self._request("POST", "/api/v1/runs", cfg)["id"]

    def status(self, run_id):
        """The run's summary: status, generation, evaluations, best error, ..."""
        return self._request("GET", f"/api/v1/runs/{run_id}")

    def runs(self):
        """Every run's summary, newest first."""
        return self._request("GET", "/api/v1/runs")["runs"]

    def wait(self, run_id, poll=1.0, timeout=None):
        """Polls until the run has ended (finished, failed or cancelled); its summary."""
        t0 = time.monotonic()
        while True:
            s = self.status(run_id)
            if s["status"] in _ENDED:
                return s
            if timeout is not None and time.monotonic() - t0 > timeout:
                raise TimeoutError(f"run {run_id}: still {s['status']} after {timeout} s")
            time.sleep(poll)

    def front(self, run_id):
        """The run's latest front (the final one once it has finished) as a :class:`Front`."""
        doc = self._request("GET", f"/api/v1/runs/{run_id}/front")
        return Front(doc, source=f"{self.url}/api/v1/runs/{run_id}/front")

    def cancel(self, run_id):
        """Asks the run to stop after its current generation."""
        return self._request("POST", f"/api/v1/runs/{run_id}/cancel", {})

    def delete(self, run_id):
        """Deletes the run and its stored fronts."""
        return self._request("DELETE", f"/api/v1/runs/{run_id}")

