#!/usr/bin/env python3
"""lgp's held-out figures across several peer runs of the same tables (an ablation).

    python3 bench/peer/compare.py base=DIR/results.json weights=DIR2/results.json [...] [-o F.md]

Each argument names an arm and its bench/peer/run.py results. The first arm is the baseline.
Prints markdown: per table and seed, every arm's best held-out RMS (and max |error|) at
ISA <= k, with Operon's figure from each arm's own run beside it (Operon is time-limited, so its
figures differ a little between runs of the same seed); then, per arm, the geometric mean over
the (table, seed) runs that both have of arm / baseline at each k (below 1: the arm is better)
and how many of the arm's per-k figures are at or below Operon's of the same run; then, per arm
and table, lgp / Operon's median and worst over seeds (the protocol's figures), and where runs
were made with --snapshots, the median and worst over seeds of the time lgp took to reach
Operon's held-out RMS.
"""
import argparse
import json
import math
import os
import statistics
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from run import KS, k_columns  # noqa: E402  (the peer protocol's ISA bounds, one list)


def load(arms):
    """[(name, {(table, seed): run})] from name=path[,path...] arguments (an arm's runs may come
    from several outputs, e.g. seeds 1-2 and seeds 3-4)."""
    out = []
    for a in arms:
        name, sep, paths = a.partition("=")
        if not sep or not name or not paths:
            sys.exit("compare: %r: expected NAME=results.json[,results.json...]" % a)
        runs = {}
        for path in paths.split(","):
            try:
                with open(path) as f:
                    res = json.load(f)
            except (OSError, ValueError) as e:
                sys.exit("compare: %s: %s" % (path, e))
            for r in res.get("runs", []):
                if (r["table"], r["seed"]) in runs:
                    sys.exit("compare: %s: %s seed %d twice in arm %s" % (path, r["table"],
                                                                         r["seed"], name))
                runs[(r["table"], r["seed"])] = r
        out.append((name, runs))
    return out


def fig(run, k, key):
    v = run["per_k"].get(str(k), {}).get(key) if run else None
    return v if isinstance(v, (int, float)) and math.isfinite(v) else None


def fmt(v):
    return "-" if v is None else "%.3g" % v


def log_ratios(arm, base, k, key):
    """log(arm / base) at k over the runs both have figures for."""
    logs = []
    for ts, run in arm.items():
        a, b = fig(run, k, key), fig(base.get(ts), k, key)
        if a and b:
            logs.append(math.log(a / b))
    return logs


def geomean_ratio(arm, base, k, key):
    """Geometric mean of arm / base at k over the runs both have figures for, and that count."""
    logs = log_ratios(arm, base, k, key)
    return (math.exp(sum(logs) / len(logs)), len(logs)) if logs else (None, 0)


# Student's t, two-sided 90 % (0.95 quantile), by degrees of freedom 1..30; beyond: 1.645.
T95 = (6.314, 2.920, 2.353, 2.132, 2.015, 1.943, 1.895, 1.860, 1.833, 1.812, 1.796, 1.782, 1.771,
       1.761, 1.753, 1.746, 1.740, 1.734, 1.729, 1.725, 1.721, 1.717, 1.714, 1.711, 1.708, 1.706,
       1.703, 1.701, 1.699, 1.697)


def geomean_interval(logs):
    """90 % interval of the geometric mean ratio (t interval on the log ratios), or None for
    fewer than 3 runs. Runs of one arm differ from each other far more than 5 %, so an ablation
    must say how sure its geometric mean is."""
    n = len(logs)
    if n < 3:
        return None
    m = sum(logs) / n
    sd = math.sqrt(sum((x - m) ** 2 for x in logs) / (n - 1))
    h = (T95[n - 2] if n - 1 <= len(T95) else 1.645) * sd / math.sqrt(n)
    return math.exp(m - h), math.exp(m + h)


def over_seeds(values, worst):
    """Median and worst of per-seed figures ("-": no figure); None counts as never (+inf)."""
    v = [math.inf if x is None else x for x in values]
    if not v:
        return "-", "-"

    def f(x):
        return "-" if math.isinf(x) else ("%.2f" if worst == "ratio" else "%.0f") % x
    return f(statistics.median(v)), f(max(v))


def seeds_table(arms):
    """Per arm and table: lgp / Operon RMS, then (with snapshots) the seconds to Operon's RMS,
    median | worst over the table's seeds at each k."""
    L = ["## Over seeds: median | worst, per arm and table", "",
         "lgp / Operon held-out RMS at ISA <= k (below 1: lgp better); where the runs wrote "
         "snapshots, lgp's search seconds to reach Operon's RMS (`-`: not within its budget).", "",
         "| arm | table | figure | seeds | " + k_columns() + " |",
         "|---|---|---|---|" + "---|" * len(KS)]
    for name, runs in arms:
        for table in sorted({t for t, _ in runs}):
            rs = [r for (t, _), r in sorted(runs.items()) if t == table]
            cells = []
            for k in KS:
                m, w = over_seeds([fig(r, k, "rms_ratio") for r in rs
                                   if fig(r, k, "rms_ratio") is not None], "ratio")
                cells.append("%s \\| %s" % (m, w))
            L.append("| %s | %s | RMS ratio | %d | %s |" % (name, table, len(rs),
                                                               " | ".join(cells)))
            timed = [r for r in rs if r.get("time_to_operon")]
            if timed:
                cells = []
                for k in KS:
                    vals = [r["time_to_operon"].get(str(k)) for r in timed
                            if fig(r, k, "operon_rms") is not None]
                    m, w = over_seeds(vals, "seconds")
                    cells.append("%s \\| %s" % (m, w) if vals else "n/a")
                L.append("| %s | %s | seconds to Operon | %d | %s |" % (
                    name, table, len(timed), " | ".join(cells)))
    return L + [""]


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
        rows = []
        for name, runs in arms[1:]:
            iv = [geomean_interval(log_ratios(runs, base, k, key)) for k in KS]
            if any(iv):
                rows.append("| %s | %s |" % (name, " | ".join(
                    "-" if v is None else "%.2f-%.2f" % v for v in iv)))
        if rows:
            L += ["90 % interval of that geometric mean (Student's t on the log ratios; a "
                  "difference is resolved only where the interval excludes 1):", "",
                  "| arm | " + k_columns() + " |", "|---|" + "---|" * len(KS)] + rows + [""]
    L += seeds_table(arms)
    return "\n".join(L)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("arms", nargs="+",
                    help="NAME=results.json[,results.json...] of bench/peer/run.py; first = base")
    ap.add_argument("-o", "--out", help="write the markdown here as well")
    args = ap.parse_args(argv)
    text = report(load(args.arms))
    print(text)
    if args.out:
        with open(args.out, "w") as f:
            f.write(text + "\n")


if __name__ == "__main__":
    main()
