#!/usr/bin/env python3
"""lgpd under stalled connections: how long the user's own request takes.

Starts lgpd on a fresh data dir, then, interleaved round by round, times GET /api/v1/runs
with no stalled connections (the baseline) and with N connections that each sent half a
request and then one header byte a second (slowloris), from 127.0.0.1 (the user's own
address: on loopback every local process is 127.0.0.1) and from 127.0.0.2. Prints the CPU
model, the median, 99th percentile and maximum of each case, and the ratio of each median to
the baseline's.

    python3 bench/daemon/slow_clients.py [--lgpd build/release/frontends/lgpd/lgpd]
        [--counts 16,100] [--requests 200] [--rounds 5]
"""
import argparse
import http.client
import os
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time


def cpu_model():
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return "unknown"


class Stalled:
    """N sockets from `src` that each sent the start of a request, then a byte a second."""

    def __init__(self, src, port, n):
        self.socks = []
        for _ in range(n):
            s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            s.bind((src, 0))
            s.connect(("127.0.0.1", port))
            s.sendall(b"GET /api/v1/runs HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: ")
            self.socks.append(s)
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._trickle, daemon=True)
        self.thread.start()

    def _trickle(self):
        while not self.stop.wait(1.0):
            for s in self.socks:
                try:
                    s.send(b"x", socket.MSG_DONTWAIT)
                except OSError:
                    pass

    def close(self):
        self.stop.set()
        self.thread.join()
        for s in self.socks:
            s.close()


def timed_get(port):
    t0 = time.perf_counter()
    c = http.client.HTTPConnection("127.0.0.1", port, timeout=30)
    c.request("GET", "/api/v1/runs")
    r = c.getresponse()
    r.read()
    c.close()
    return (time.perf_counter() - t0) * 1000.0, r.status


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--lgpd", default="build/release/frontends/lgpd/lgpd")
    ap.add_argument("--counts", default="16,100")
    ap.add_argument("--requests", type=int, default=200, help="per case and round")
    ap.add_argument("--rounds", type=int, default=5)
    args = ap.parse_args()
    counts = [int(x) for x in args.counts.split(",")]

    print(f"CPU: {cpu_model()} ({os.cpu_count()} logical CPUs)")
    with tempfile.TemporaryDirectory() as tmp:
        port_file = os.path.join(tmp, "port")
        proc = subprocess.Popen(
            [args.lgpd, "--data-dir", os.path.join(tmp, "state"), "--listen", "127.0.0.1:0",
             "--port-file", port_file, "--log-level", "warn"])
        try:
            for _ in range(200):
                if os.path.exists(port_file):
                    break
                time.sleep(0.05)
            port = int(open(port_file).read())
            cases = [("baseline", None, 0)] + [(f"{n} from {src}", src, n)
                                               for src in ("127.0.0.1", "127.0.0.2")
                                               for n in counts]
            times = {name: [] for name, _, _ in cases}
            failures = {name: 0 for name, _, _ in cases}
            for _ in range(args.rounds):
                for name, src, n in cases:
                    stalled = Stalled(src, port, n) if n else None
                    time.sleep(0.2)
                    for _ in range(args.requests):
                        ms, status = timed_get(port)
                        times[name].append(ms)
                        failures[name] += status != 200
                    if stalled:
                        stalled.close()
            base = statistics.median(times["baseline"])
            print(f"{args.rounds} rounds x {args.requests} requests per case, interleaved")
            print(f"{'case':>22} {'median ms':>10} {'p99 ms':>8} {'max ms':>8} "
                  f"{'vs baseline':>12} {'non-200':>8}")
            for name, _, _ in cases:
                t = sorted(times[name])
                med = statistics.median(t)
                p99 = t[min(len(t) - 1, int(0.99 * len(t)))]
                print(f"{name:>22} {med:10.2f} {p99:8.2f} {t[-1]:8.2f} {med / base:11.2f}x "
                      f"{failures[name]:8d}")
        finally:
            proc.send_signal(signal.SIGTERM)
            proc.wait(timeout=30)
    return 0


if __name__ == "__main__":
    sys.exit(main())
