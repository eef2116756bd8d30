#!/usr/bin/env python3
"""Exact recovery in short runs: lgp.Regressor with its defaults on AI Feynman equations.

    PYTHONPATH=build/release/python python3 bench/recovery/feynman_regressor.py --out DIR \
        [--seconds 30] [--generations G] [--seeds N|a,b] [--equations I.12.1,...] [--label NAME]

For every equation (the AI Feynman set of Udrescu and Tegmark, "AI Feynman: a physics-inspired
method for symbolic regression", Science Advances 6(16), 2020, with the input ranges of its
FeynmanEquations.csv; the SRBench protocol of La Cava et al., NeurIPS 2021, counts these as
ground-truth problems) and seed: 1,000 training rows drawn uniformly over the ranges, 1,000
held-out rows from another draw; lgp.Regressor() with nothing but ``seconds`` (default 30),
``threads=1`` and ``random_state`` set; the chosen member (the Regressor's default, the most
accurate) predicted in double precision on the held-out rows. **Exact** = held-out
R^2 >= 1 - 1e-12 (the definition of issue 51); ``near`` = R^2 >= 0.999 as well.

Writes DIR/results.json (per equation and seed: R^2, formula, seconds) and DIR/report.md, after
every run (a stopped benchmark keeps what it did). To compare two engines, run the script once
per engine with PYTHONPATH at each build's python/ folder (side by side, one core each) and
compare the counts. The report counts how the runs stopped: in engines older than the
``--generations`` option, Regressor(seconds=S) also kept its default of 100 generations, which
ends a run after about a second; ``--generations 0`` gives such an engine the whole S seconds.
"""
import argparse
import json
import math
import os
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "peer"))
from run import cpu_model  # noqa: E402  (the benchmarks' one CPU description)

PI = math.pi

# name: (formula text, [(input, lo, hi)], f(*columns))
EQUATIONS = {
    "I.6.2a": ("exp(-theta^2/2)/sqrt(2 pi)", [("theta", 1, 3)],
               lambda t: np.exp(-t**2 / 2) / np.sqrt(2 * PI)),
    "I.6.2": ("exp(-(theta/sigma)^2/2)/(sqrt(2 pi) sigma)", [("sigma", 1, 3), ("theta", 1, 3)],
              lambda s, t: np.exp(-(t / s)**2 / 2) / (np.sqrt(2 * PI) * s)),
    "I.8.14": ("sqrt((x2-x1)^2+(y2-y1)^2)",
               [("x1", 1, 5), ("x2", 1, 5), ("y1", 1, 5), ("y2", 1, 5)],
               lambda x1, x2, y1, y2: np.sqrt((x2 - x1)**2 + (y2 - y1)**2)),
    "I.10.7": ("m0/sqrt(1-v^2/c^2)", [("m0", 1, 5), ("v", 1, 2), ("c", 3, 10)],
               lambda m, v, c: m / np.sqrt(1 - v**2 / c**2)),
    "I.11.19": ("x1 y1 + x2 y2 + x3 y3",
                [("x1", 1, 5), ("x2", 1, 5), ("x3", 1, 5), ("y1", 1, 5), ("y2", 1, 5),
                 ("y3", 1, 5)],
                lambda x1, x2, x3, y1, y2, y3: x1 * y1 + x2 * y2 + x3 * y3),
    "I.12.1": ("mu Nn", [("mu", 1, 5), ("Nn", 1, 5)], lambda m, n: m * n),
    "I.12.2": ("q1 q2/(4 pi eps r^2)",
               [("q1", 1, 5), ("q2", 1, 5), ("eps", 1, 5), ("r", 1, 5)],
               lambda q1, q2, e, r: q1 * q2 / (4 * PI * e * r**2)),
    "I.12.4": ("q1/(4 pi eps r^2)", [("q1", 1, 5), ("eps", 1, 5), ("r", 1, 5)],
               lambda q, e, r: q / (4 * PI * e * r**2)),
    "I.12.5": ("q2 Ef", [("q2", 1, 5), ("Ef", 1, 5)], lambda q, e: q * e),
    "I.13.4": ("m (v^2+u^2+w^2)/2", [("m", 1, 5), ("v", 1, 5), ("u", 1, 5), ("w", 1, 5)],
               lambda m, v, u, w: 0.5 * m * (v**2 + u**2 + w**2)),
    "I.13.12": ("G m1 m2 (1/r2 - 1/r1)",
                [("m1", 1, 5), ("m2", 1, 5), ("r1", 1, 5), ("r2", 1, 5), ("G", 1, 5)],
                lambda m1, m2, r1, r2, g: g * m1 * m2 * (1 / r2 - 1 / r1)),
    "I.14.3": ("m g z", [("m", 1, 5), ("g", 1, 5), ("z", 1, 5)], lambda m, g, z: m * g * z),
    "I.14.4": ("k x^2/2", [("k", 1, 5), ("x", 1, 5)], lambda k, x: 0.5 * k * x**2),
    "I.15.3x": ("(x-u t)/sqrt(1-u^2/c^2)", [("x", 5, 10), ("u", 1, 2), ("c", 3, 20), ("t", 1, 2)],
                lambda x, u, c, t: (x - u * t) / np.sqrt(1 - u**2 / c**2)),
    "I.16.6": ("(u+v)/(1+u v/c^2)", [("c", 1, 5), ("v", 1, 5), ("u", 1, 5)],
               lambda c, v, u: (u + v) / (1 + u * v / c**2)),
    "I.18.4": ("(m1 r1 + m2 r2)/(m1+m2)", [("m1", 1, 5), ("m2", 1, 5), ("r1", 1, 5), ("r2", 1, 5)],
               lambda m1, m2, r1, r2: (m1 * r1 + m2 * r2) / (m1 + m2)),
    "I.24.6": ("m (w^2+w0^2) x^2/4", [("m", 1, 3), ("w", 1, 2), ("w0", 3, 5), ("x", 1, 2)],
               lambda m, w, w0, x: 0.25 * m * (w**2 + w0**2) * x**2),
    "I.25.13": ("q/C", [("q", 1, 5), ("C", 1, 5)], lambda q, c: q / c),
    "I.27.6": ("1/(1/d1+n/d2)", [("d1", 1, 5), ("d2", 1, 5), ("n", 1, 5)],
               lambda d1, d2, n: 1 / (1 / d1 + n / d2)),
    "I.29.4": ("omega/c", [("omega", 1, 10), ("c", 1, 10)], lambda w, c: w / c),
    "I.32.5": ("q^2 a^2/(6 pi eps c^3)", [("q", 1, 5), ("a", 1, 5), ("eps", 1, 5), ("c", 1, 5)],
               lambda q, a, e, c: q**2 * a**2 / (6 * PI * e * c**3)),
    "I.34.8": ("q v B/p", [("q", 1, 5), ("v", 1, 5), ("B", 1, 5), ("p", 1, 5)],
               lambda q, v, b, p: q * v * b / p),
    "I.34.27": ("h omega/(2 pi)", [("omega", 1, 5), ("h", 1, 5)],
                lambda w, h: h / (2 * PI) * w),
    "I.39.10": ("3/2 pF V", [("pF", 1, 5), ("V", 1, 5)], lambda p, v: 1.5 * p * v),
    "I.39.11": ("pF V/(gamma-1)", [("gamma", 2, 5), ("pF", 1, 5), ("V", 1, 5)],
                lambda g, p, v: p * v / (g - 1)),
    "I.39.22": ("n kb T/V", [("n", 1, 5), ("T", 1, 5), ("V", 1, 5), ("kb", 1, 5)],
                lambda n, t, v, k: n * k * t / v),
    "I.43.31": ("mob kb T", [("mob", 1, 5), ("T", 1, 5), ("kb", 1, 5)],
                lambda m, t, k: m * k * t),
    "I.47.23": ("sqrt(gamma pr/rho)", [("gamma", 1, 5), ("pr", 1, 5), ("rho", 1, 5)],
                lambda g, p, r: np.sqrt(g * p / r)),
    "II.2.42": ("kappa (T2-T1) A/d",
                [("kappa", 1, 5), ("T1", 1, 5), ("T2", 1, 5), ("A", 1, 5), ("d", 1, 5)],
                lambda k, t1, t2, a, d: k * (t2 - t1) * a / d),
    "II.3.24": ("P/(4 pi r^2)", [("P", 1, 5), ("r", 1, 5)], lambda p, r: p / (4 * PI * r**2)),
    "II.4.23": ("q/(4 pi eps r)", [("q", 1, 5), ("eps", 1, 5), ("r", 1, 5)],
                lambda q, e, r: q / (4 * PI * e * r)),
    "II.8.31": ("eps Ef^2/2", [("eps", 1, 5), ("Ef", 1, 5)], lambda e, f: 0.5 * e * f**2),
    "II.11.28": ("1 + n alpha/(1 - n alpha/3)", [("n", 0, 1), ("alpha", 0, 1)],
                 lambda n, a: 1 + n * a / (1 - n * a / 3)),
    "II.27.16": ("eps c Ef^2", [("eps", 1, 5), ("c", 1, 5), ("Ef", 1, 5)],
                 lambda e, c, f: e * c * f**2),
    "II.38.14": ("Y/(2 (1+sigma))", [("Y", 1, 5), ("sigma", 1, 5)],
                 lambda y, s: y / (2 * (1 + s))),
    "III.12.43": ("n h/(2 pi)", [("n", 1, 5), ("h", 1, 5)], lambda n, h: n * h / (2 * PI)),
}

EXACT = 1 - 1e-12
NEAR = 0.999


def draw(spec, rows, rng):
    return np.column_stack([rng.uniform(lo, hi, rows) for _, lo, hi in spec])


def r2(y, p):
    ss = float(np.sum((y - y.mean())**2))
    res = float(np.sum((y - p)**2))
    return 1 - res / ss if ss > 0 and math.isfinite(res) else -math.inf


def run_one(lgp, name, seed, seconds, generations=None):
    text, spec, f = EQUATIONS[name]
    # The rows depend on the equation and seed only: every engine fits the same data.
    rng = np.random.default_rng([seed, sorted(EQUATIONS).index(name)])
    X, Xh = draw(spec, 1000, rng), draw(spec, 1000, rng)
    y, yh = f(*X.T), f(*Xh.T)
    t0 = time.monotonic()
    budget = {} if generations is None else {"generations": generations}
    m = lgp.Regressor(seconds=seconds, threads=1, random_state=seed, **budget).fit(X, y)
    wall = time.monotonic() - t0
    progress = getattr(m.front_, "progress", None) or {}
    p = m.model_.predict(Xh, double_precision=True)
    v = r2(yh, p)
    return {"equation": name, "truth": text, "seed": seed, "r2": v, "exact": v >= EXACT,
            "near": v >= NEAR, "formula": m.formula_, "wall_s": wall,
            "generations": progress.get("generation"), "stop": progress.get("stop_reason")}


def stops(runs):
    """How the runs ended (the engine's stop reasons, counted): shows which budget applied."""
    counts = {}
    for r in runs:
        key = r.get("stop") or "not reported"
        counts[key] = counts.get(key, 0) + 1
    return ", ".join("%s %d" % kv for kv in sorted(counts.items()))


def report(meta, runs):
    n = len(runs)
    exact = sum(r["exact"] for r in runs)
    near = sum(r["near"] for r in runs)
    L = ["# lgp.Regressor on AI Feynman equations (`feynman_regressor.py`)", "",
         "Engine: %s. CPU: %s. Regressor(seconds=%g, threads=1%s), the rest its defaults; "
         "1,000 training and 1,000 held-out rows per equation and seed. Stops: %s; median "
         "wall time %.3g s." % (meta["label"], meta["cpu"], meta["seconds"],
                                "" if meta.get("generations") is None
                                else ", generations=%d" % meta["generations"],
                                stops(runs), statistics.median(r["wall_s"] for r in runs)), "",
         "**Exact (held-out R^2 >= 1 - 1e-12): %d of %d runs**; R^2 >= 0.999: %d of %d." % (
             exact, n, near, n), "",
         "| equation | truth | seed | held-out R^2 | exact | formula |", "|---|---|---|---|---|---|"]
    for r in runs:
        L.append("| %s | `%s` | %d | %.15g | %s | `%s` |" % (
            r["equation"], r["truth"], r["seed"], r["r2"], "yes" if r["exact"] else "",
            r["formula"].replace("|", "\\|")))
    L += ["", "```sh", meta["command"], "```", ""]
    return "\n".join(L)


def parse_seeds(text):
    """"3" -> [1, 2, 3]; "2,3" -> [2, 3]; [] where the text is not one of those."""
    try:
        parts = [int(t) for t in text.split(",") if t.strip()]
    except ValueError:
        return []
    if "," not in text:
        parts = list(range(1, parts[0] + 1)) if parts else []
    return parts if parts and all(p >= 1 for p in parts) else []


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--seeds", default="1", help="N: seeds 1..N per equation; or a list, "
                    "e.g. 2,3 (to split one measurement between cores)")
    ap.add_argument("--equations", default="", help="comma-separated names (default: all)")
    ap.add_argument("--generations", type=int, default=None,
                    help="pass generations=G as well (0: no generation cap; an engine whose "
                    "Regressor capped a seconds budget at 100 generations then runs the seconds)")
    ap.add_argument("--label", default="", help="the engine's name in the report")
    args = ap.parse_args(argv)
    names = [e for e in args.equations.split(",") if e] or list(EQUATIONS)
    for e in names:
        if e not in EQUATIONS:
            ap.error("unknown equation %r (known: %s)" % (e, ", ".join(EQUATIONS)))
    seeds = parse_seeds(args.seeds)
    if not args.seconds > 0 or not seeds:
        ap.error("--seconds must be > 0 and --seeds a count >= 1 or a list of seeds >= 1")
    if args.generations is not None and args.generations < 0:
        ap.error("--generations must be >= 0")
    import lgp  # the engine under test: PYTHONPATH picks the build
    os.makedirs(args.out, exist_ok=True)
    meta = {"label": args.label or os.path.dirname(os.path.dirname(lgp.__file__)),
            "cpu": cpu_model(), "seconds": args.seconds, "generations": args.generations,
            "command": " ".join([os.path.basename(sys.executable)] + sys.argv)}
    runs = []
    for name in names:
        for seed in seeds:
            runs.append(run_one(lgp, name, seed, args.seconds, args.generations))
            r = runs[-1]
            print("%-10s seed %d  R^2 %.15g%s" % (name, seed, r["r2"], "  exact" if r["exact"]
                                                   else ""), flush=True)
            with open(os.path.join(args.out, "results.json"), "w") as f:
                json.dump({"meta": meta, "runs": runs}, f, indent=1)
            with open(os.path.join(args.out, "report.md"), "w") as f:
                f.write(report(meta, runs))
    print("exact: %d of %d" % (sum(r["exact"] for r in runs), len(runs)))


if __name__ == "__main__":
    main()
