"""lgp.Daemon: a client of lgpd's HTTP API (frontends/lgpd/README.md), standard library only."""

import json
import time
import urllib.error
import urllib.request


from . import _config
from ._fit import Table, _arrays
from ._front import Front

_ENDED = ("finished", "failed", "cancelled")


class DaemonError(ValueError):
    """A request lgpd refused: ``status`` is the HTTP status, ``field`` the config field it
    names (for a 400), else None."""

    def __init__(self, message, status, field=None):
        super().__init__(message)
        self.status = status
        self.field = field


class Daemon:
    """A connection to a running lgpd, e.g. ``Daemon("http://127.0.0.1:8737", token=...)``.

    ``submit`` queues a run and returns its id; ``status``, ``wait``, ``front``, ``cancel``,
    ``delete`` and ``runs`` follow the HTTP API. Refusals raise :class:`DaemonError` (a
    ValueError) with lgpd's message; an unreachable daemon raises ConnectionError.
    """

    def __init__(self, url="http://127.0.0.1:8737", token=None, timeout=30.0):
        if not isinstance(url, str) or not url.startswith(("http://", "https://")):
            raise ValueError(f"url: must start with http:// or https:// (got {url!r})")
        self.url = url.rstrip("/")
        self.token = token
        self.timeout = timeout

    def _request(self, method, path, body=None):
        headers = {"Accept": "application/json"}
        data = None
        if body is not None:
            data = json.dumps(body).encode()
            headers["Content-Type"] = "application/json"
        if self.token:
            headers["Authorization"] = f"Bearer {self.token}"
        req = urllib.request.Request(self.url + path, data=data, method=method, headers=headers)
        try:
            with urllib.request.urlopen(req, timeout=self.timeout) as r:
                return json.loads(r.read().decode())
        except urllib.error.HTTPError as e:
            text = e.read().decode(errors="replace")
            try:
                doc = json.loads(text)
                msg, field = doc.get("error", text), doc.get("field")
            except ValueError:
                msg, field = text.strip() or e.reason, None
            raise DaemonError(f"lgpd: {method} {path}: {e.code}: {msg}", e.code, field) from None
        except urllib.error.URLError as e:
            raise ConnectionError(f"lgpd at {self.url}: {e.reason}") from None

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

