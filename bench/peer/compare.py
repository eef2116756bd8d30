#!/usr/bin/env python3
"""lgp's held-out figures across several peer runs of the same tables (an ablation).

    python3 bench/peer/compare.py base=DIR/results.json weights=DIR2/results.json [...] [-o F.md]

Each argument names an arm and its bench/peer/run.py results. The first arm is the baseline.
Prints markdown: per table and seed, every arm's best held-out RMS (and max |error|) at
ISA <= k, with Operon's figure from each arm's own run beside it (Operon is time-limited, so its
figures differ a little between runs of the same seed); then, per arm, the geometric mean over
the (table, seed) runs that both have of arm / baseline at each k (below 1: the arm is better)
and how many of the arm's per-k figures are at or below Operon's of the same run.
"""
import argparse
import json
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from run import KS, k_columns  # noqa: E402  (the peer protocol's ISA bounds, one list)


def load(arms):
    """[(name, {(table, seed): run})] from name=path arguments."""
    out = []
    for a in arms:
        name, sep, path = a.partition("=")
        if not sep or not name or not path:
            sys.exit("compare: %r: expected NAME=results.json" % a)
        try:
            with open(path) as f:
                res = json.load(f)
        except (OSError, ValueError) as e:
            sys.exit("compare: %s: %s" % (path, e))
        out.append((name, {(r["table"], r["seed"]): r for r in res.get("runs", [])}))
    return out


def fig(run, k, key):
    v = run["per_k"].get(str(k), {}).get(key) if run else None
    return v if isinstance(v, (int, float)) and math.isfinite(v) else None


def fmt(v):
    return "-" if v is None else "%.3g" % v


def geomean_ratio(arm, base, k, key):
    """Geometric mean of arm / base at k over the runs both have figures for, and that count."""
    logs = []
    for ts, run in arm.items():
        a, b = fig(run, k, key), fig(base.get(ts), k, key)
        if a and b:
            logs.append(math.log(a / b))
    return (math.exp(sum(logs) / len(logs)), len(logs)) if logs else (None, 0)


def report(arms):
    L = []
    keys = sorted({ts for _, runs in arms for ts in runs})
    for metric, key, okey in (("RMS", "lgp_rms", "operon_rms"), ("max |error|", "lgp_max",
                                                                  "operon_max")):
        L += ["## lgp's best held-out %s at ISA <= k, per arm (Operon of the same run)" % metric,
              ""]
        for t, s in keys:
            L += ["%s, seed %d:" % (t, s), "",
                  "| arm | " + k_columns() + " |",
                  "|---|" + "---|" * len(KS)]
            for name, runs in arms:
                run = runs.get((t, s))
                if run:
                    L.append("| %s | " % name + " | ".join(
                        "%s (%s)" % (fmt(fig(run, k, key)), fmt(fig(run, k, okey))) for k in KS)
                        + " |")
            L.append("")
        base_name, base = arms[0]
        L += ["### %s: arm / %s, geometric mean over runs (below 1: better than %s)" %
              (metric, base_name, base_name), "",
              "| arm | runs | " + k_columns() + " | at or below Operon |",
              "|---|---|" + "---|" * (len(KS) + 1)]
        for name, runs in arms:
            cells, n = [], 0
            for k in KS:
                g, c = geomean_ratio(runs, base, k, key)
                cells.append("-" if g is None else "%.2f" % g)
                n = max(n, c)
            wins = total = 0
            for run in runs.values():
                for k in KS:
                    a, o = fig(run, k, key), fig(run, k, okey)
                    if a is not None and o is not None:
                        total += 1
                        wins += a <= o
            L.append("| %s | %d | %s | %d of %d |" % (name, n, " | ".join(cells), wins, total))
        L.append("")
    return "\n".join(L)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("arms", nargs="+", help="NAME=results.json of bench/peer/run.py; first = base")
    ap.add_argument("-o", "--out", help="write the markdown here as well")
    args = ap.parse_args(argv)
    text = report(load(args.arms))
    print(text)
    if args.out:
        with open(args.out, "w") as f:
            f.write(text + "\n")


if __name__ == "__main__":
    main()
