#!/usr/bin/env python3
"""lgp next to Operon on the split-sum DFG table, one channel at a time.

Builds the 64 x 64 DFG table (examples/scenes/dfg_64.json, through `lgp data --csv`), writes
two single-output channels, F0 = 1 (y = A + B) and F0 = 0.04 (y = 0.04 A + B), and for each
starts `lgp run` and Operon's `operon_nsgp` together, one thread each, with the same wall
budget and seed. Reports per channel the best RMS of each engine's final front, lgp's largest
cost, Operon's tree length and its best RMS at length <= 25, as a markdown table (printed and
written to DIR/report.md) and DIR/results.json, with the CPU model and the exact commands.

    python3 bench/dfg_peer/run.py --out DIR [--budget 120] [--seed 1] [--operon PATH]
        [--lgp build/release/frontends/lgp] [--quick]

Operon comes from --operon or $OPERON_NSGP; it is a peer measured against, never a dependency.
See bench/dfg_peer/README.md for the protocol and how each figure is computed.
"""
import argparse
import csv
import json
import math
import os
import re
import shlex
import signal
import subprocess
import sys
import threading
import time

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SCENE = os.path.join(REPO, "examples", "scenes", "dfg_64.json")
CHANNELS = [("F0=1", "f0_1", 1.0), ("F0=0.04", "f0_0p04", 0.04)]  # name, file stem, weight of A
OPERON_SYMBOLS = "add,sub,mul,div,exp,log,sqrt,pow,square,fmin,fmax,abs"
OPERON_SHORT = 25  # the length bound of the "short model" column


def cpu_model():
    try:
        with open("/proc/cpuinfo") as f:
            names = [l.split(":", 1)[1].strip() for l in f if l.startswith("model name")]
        if names:
            return "%s (%d logical CPUs)" % (names[0], len(names))
    except OSError:
        pass
    return "unknown"


def fmt(x, spec=".3e"):
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else format(x, spec)


# --- the table and its channels ---------------------------------------------------------------


def make_table(lgp, out):
    path = os.path.join(out, "dfg_64.csv")
    cmd = [lgp, "data", SCENE, "-o", path, "--csv", "-q"]
    subprocess.run(cmd, check=True)
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if len(rows) != 64 * 64 or set(rows[0]) != {"mu", "r", "A", "B"}:
        sys.exit("error: %s: expected 4096 rows of mu,r,A,B" % path)
    return cmd, rows


def write_channel(rows, weight, path):
    """The channel y = weight * A + B as CSV mu,r,y; returns (mu, r, y) as floats."""
    mu, r, y = [], [], []
    with open(path, "w") as f:
        f.write("mu,r,y\n")
        for row in rows:
            v = weight * float(row["A"]) + float(row["B"])
            f.write("%s,%s,%r\n" % (row["mu"], row["r"], v))
            mu.append(float(row["mu"]))
            r.append(float(row["r"]))
            y.append(v)
    return mu, r, y


def population_variance(y):
    m = sum(y) / len(y)
    return sum((v - m) ** 2 for v in y) / len(y)


# --- Operon's infix models, evaluated in double precision -------------------------------------
# The InfixFormatter of operon_nsgp (source/formatter/infix.cpp) parenthesises every operation:
# numbers, variables, (a op b op ...) with + - * / ^, (-a), (1 / a), and f(a) or min/max(a, b).

_TOKEN = re.compile(r"\s*(?:(\d+\.?\d*(?:[eE][-+]?\d+)?)|([A-Za-z_][A-Za-z_0-9]*)|(.))")


def _tokens(text):
    toks, pos = [], 0
    text = text.strip()
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if m is None or m.end() == pos:
            break
        pos = m.end()
        num, name, op = m.groups()
        toks.append(("num", float(num)) if num else ("name", name) if name else ("op", op))
    return toks


def _fmin(a, b):  # std::fmin: a NaN operand yields the other
    return b if math.isnan(a) else a if math.isnan(b) else min(a, b)


def _fmax(a, b):
    return b if math.isnan(a) else a if math.isnan(b) else max(a, b)


def _div(a, b):  # IEEE division, as Operon's float32 evaluation does it
    if b != 0 or math.isnan(b):
        return a / b
    if a == 0 or math.isnan(a):
        return math.nan
    return math.copysign(math.inf, a) * math.copysign(1.0, b)


def _guard(f):
    def g(*a):
        try:
            return f(*a)
        except OverflowError:
            return math.inf
        except (ValueError, ZeroDivisionError):
            return math.nan

    return g


_FUNCS = {
    "exp": _guard(math.exp), "log": _guard(math.log), "sqrt": _guard(math.sqrt),
    "abs": abs, "min": _fmin, "max": _fmax, "pow": _guard(math.pow),
}
_BIN = {
    "+": lambda a, b: a + b, "-": lambda a, b: a - b, "*": lambda a, b: a * b,
    "/": _div, "^": _guard(math.pow),
}


def parse_operon(text):
    """A function of a dict of variables, or None when the text is not understood."""
    toks = _tokens(text)
    pos = [0]

    def peek():
        return toks[pos[0]] if pos[0] < len(toks) else ("end", None)

    def take(kind=None, value=None):
        t = peek()
        if (kind and t[0] != kind) or (value is not None and t[1] != value):
            raise ValueError("expected %s at token %d" % (value or kind, pos[0]))
        pos[0] += 1
        return t

    def binary(ops, sub):
        def level():
            left = sub()
            while peek()[0] == "op" and peek()[1] in ops:
                op = _BIN[take()[1]]
                right = sub()
                left = (lambda l, r, o: lambda v: o(l(v), r(v)))(left, right, op)
            return left

        return level

    def unary():
        if peek() == ("op", "-"):
            take()
            a = unary()
            return lambda v: -a(v)
        return primary()

    def primary():
        kind, val = take()
        if kind == "num":
            return lambda v: val
        if kind == "op" and val == "(":
            e = expr()
            take("op", ")")
            return e
        if kind == "name":
            if peek() == ("op", "("):
                take()
                args = [expr()]
                while peek() == ("op", ","):
                    take()
                    args.append(expr())
                take("op", ")")
                f = _FUNCS[val]
                return lambda v: f(*[a(v) for a in args])
            return lambda v: v[val]
        raise ValueError("unexpected %r" % (val,))

    power = binary("^", unary)
    term = binary("*/", power)
    expr = binary("+-", term)
    try:
        e = expr()
        if pos[0] != len(toks):
            return None
        return e
    except (ValueError, KeyError):
        return None


def rms_of(model, mu, r, y):
    f = parse_operon(model)
    if f is None:
        return None
    s = 0.0
    for a, b, t in zip(mu, r, y):
        try:
            p = f({"mu": a, "r": b})
        except (ValueError, OverflowError, ZeroDivisionError):
            return math.nan
        s += (p - t) * (p - t)
    return math.sqrt(s / len(y))


# --- one channel: both engines together -------------------------------------------------------


def merge_patch(target, patch):
    """RFC 7386 JSON merge patch (as lgp_recovery's --config-json): null deletes a key."""
    if not isinstance(patch, dict):
        return patch
    out = dict(target) if isinstance(target, dict) else {}
    for k, v in patch.items():
        if v is None:
            out.pop(k, None)
        else:
            out[k] = merge_patch(out.get(k), v)
    return out


def lgp_config(data_csv, budget, seed, front_json, front_csv, patch=None):
    cfg = {
        "data": {"path": os.path.basename(data_csv), "inputs": ["mu", "r"], "outputs": ["y"]},
        "objectives": {"error": "rmse"},
        "search": {"linear_scaling": True, "threads": 1, "wall_time_s": budget,
                   "generations": 0, "seed": seed},
        "output": {"front_json": os.path.basename(front_json),
                   "front_csv": os.path.basename(front_csv)},
    }
    # The protocol keys (budget, thread, seed, files) always win over the patch.
    fixed = {"search": {k: cfg["search"][k] for k in ("threads", "wall_time_s", "generations",
                                                       "seed")},
             "data": cfg["data"], "output": cfg["output"]}
    return merge_patch(merge_patch(cfg, patch or {}), fixed)


def operon_args(exe, data_csv, rows, budget, seed):
    return [exe, "--dataset", data_csv, "--target", "y", "--inputs", "mu,r",
            "--train", "0:%d" % rows, "--test", "0:%d" % rows,
            "--population-size", "1000", "--pool-size", "1000",
            "--generations", "100000", "--evaluations", "1000000000",
            "--iterations", "5", "--timelimit", str(budget), "--threads", "1",
            "--seed", str(seed), "--enable-symbols", OPERON_SYMBOLS]


def run_together(jobs, deadline_s):
    """Starts every job at once; waits for all. Returns per job (exit code, wall s, cpu s)."""
    procs, t0 = [], {}
    for j in jobs:
        with open(j["stdout"], "w") as out, open(j["stderr"], "w") as err:
            p = subprocess.Popen(j["argv"], stdout=out, stderr=err, cwd=j["cwd"],
                                 env=dict(os.environ, **j["env"]))
        procs.append(p)
        t0[p.pid] = time.monotonic()
    killed = []

    def watchdog():  # a run far past its budget is stopped: SIGTERM, then SIGKILL
        for sig in (signal.SIGTERM, signal.SIGKILL):
            for p in procs:
                if p.returncode is None:
                    try:
                        os.kill(p.pid, sig)
                        killed.append(p.pid)
                    except ProcessLookupError:
                        pass
            time.sleep(10)

    timer = threading.Timer(deadline_s, watchdog)
    timer.daemon = True
    timer.start()
    result = {}
    for _ in procs:  # wait4 on any of ours gives the child's own CPU time and its end time
        pid, status, usage = os.wait4(-1, 0)
        p = next(q for q in procs if q.pid == pid)
        p.returncode = os.waitstatus_to_exitcode(status)
        result[pid] = (p.returncode, time.monotonic() - t0[pid], usage.ru_utime + usage.ru_stime,
                       pid in killed)
    timer.cancel()
    return [result[p.pid] for p in procs]


def read_lgp_front(path):
    with open(path) as f:
        front = json.load(f)
    if front.get("error_metric") != "rmse" or front.get("error_channels") != ["y"]:
        sys.exit("error: %s: expected error_metric rmse on output y" % path)
    members = front["members"]
    best = min(members, key=lambda m: m["error"])
    out = best["outputs"][0]
    return {
        "members": len(members),
        "best_rms_float32": best["error"],
        "best_rms_double": out["double"]["rmse"],
        "best_max_abs_double": out["double"]["max_abs"],
        "best_cost": best["cost"],
        "largest_cost": max(m["cost"] for m in members),
        "best_formula": best["formula"],
        "generations": front["progress"]["generation"],
        "evaluations": front["progress"]["evaluations"],
        "search_s": front["progress"]["elapsed_s"],
        "stop_reason": front["progress"]["stop_reason"],
    }


def read_operon(stdout_path, front_path, var_y, mu, r, y):
    rows = []
    with open(front_path, newline="") as f:
        for row in csv.DictReader(f):
            nmse = float(row["nmse_train"])
            rows.append({"length": int(row["length"]), "nmse": nmse,
                         "rms": math.sqrt(nmse * var_y) if nmse >= 0 else math.nan,
                         "model": row["model"]})
    rows = [x for x in rows if not math.isnan(x["rms"])]
    if not rows:
        sys.exit("error: %s: no finite front member" % front_path)
    best = min(rows, key=lambda x: x["rms"])
    short = [x for x in rows if x["length"] <= OPERON_SHORT]
    best_short = min(short, key=lambda x: x["rms"]) if short else None
    last = None  # the last generation row: iteration ... eval_cnt ... elapsed
    with open(stdout_path) as f:
        lines = f.read().splitlines()
    header = next((l.split() for l in lines if l.startswith("iteration")), None)
    for l in lines:
        w = l.split()
        if header and len(w) == len(header) and re.fullmatch(r"\d+", w[0]):
            last = dict(zip(header, w))
    return {
        "members": len(rows),
        "best_rms": best["rms"],
        "best_rms_double": rms_of(best["model"], mu, r, y),
        "best_length": best["length"],
        "best_model": best["model"],
        "short_rms": best_short["rms"] if best_short else None,
        "short_length": best_short["length"] if best_short else None,
        "short_model": best_short["model"] if best_short else None,
        "generations": int(last["iteration"]) + 1 if last else None,
        "evaluations": int(last["eval_cnt"]) if last else None,
        "search_s": float(last["elapsed"]) if last else None,
    }


def run_channel(args, name, stem, weight, rows, out):
    d = os.path.join(out, stem)
    os.makedirs(d, exist_ok=True)
    data_csv = os.path.join(d, stem + ".csv")
    mu, r, y = write_channel(rows, weight, data_csv)
    var_y = population_variance(y)

    cfg_path = os.path.join(d, "lgp.json")
    front_json = os.path.join(d, "lgp-front.json")
    front_csv = os.path.join(d, "lgp-front.csv")
    with open(cfg_path, "w") as f:
        json.dump(lgp_config(data_csv, args.budget, args.seed, front_json, front_csv,
                             args.config_patch), f, indent=2)
        f.write("\n")
    operon_front = os.path.join(d, "operon-front.csv")
    jobs = [
        {"argv": [args.lgp, "run", cfg_path], "env": {}, "cwd": d,
         "stdout": os.path.join(d, "lgp.out"), "stderr": os.path.join(d, "lgp.err")},
        {"argv": operon_args(args.operon, data_csv, len(y), args.budget, args.seed),
         "env": {"OPERON_PARETO_FRONT": operon_front}, "cwd": d,
         "stdout": os.path.join(d, "operon.out"), "stderr": os.path.join(d, "operon.err")},
    ]
    for path in (front_json, operon_front):
        if os.path.exists(path):
            os.remove(path)
    commands = ["(cd %s && %s%s)" % (shlex.quote(j["cwd"]),
                                    "".join("%s=%s " % (k, shlex.quote(v))
                                            for k, v in j["env"].items()),
                                    shlex.join(j["argv"])) for j in jobs]
    print("[%s] lgp and Operon together, %g s each ..." % (name, args.budget), flush=True)
    (lrc, lwall, lcpu, lkill), (orc, owall, ocpu, okill) = run_together(
        jobs, deadline_s=3 * args.budget + 120)
    for label, rc, j in (("lgp", lrc, jobs[0]), ("operon", orc, jobs[1])):
        if rc != 0:
            sys.exit("error: %s exited %d; see %s" % (label, rc, j["stderr"]))
    lgp_res = read_lgp_front(front_json)
    op_res = read_operon(jobs[1]["stdout"], operon_front, var_y, mu, r, y)
    lgp_res.update(wall_s=lwall, cpu_s=lcpu, killed=lkill)
    op_res.update(wall_s=owall, cpu_s=ocpu, killed=okill)
    return {"channel": name, "weight_A": weight, "rows": len(y), "var_y": var_y,
            "data": data_csv, "lgp_config": cfg_path, "commands": commands,
            "lgp": lgp_res, "operon": op_res}


# --- the report -------------------------------------------------------------------------------


def code_span(text):
    """A markdown code span that holds any text: a fence longer than its longest backtick run."""
    longest = max((len(m) for m in re.findall(r"`+", text)), default=0)
    pad = " " if longest else ""
    return "`" * (longest + 1) + pad + text + pad + "`" * (longest + 1)


def report(meta, results):
    L = ["# lgp and Operon on the split-sum DFG table", ""]
    L.append("CPU: %s. Load average at the start: %s. Budget %g s wall per engine, seed %d, "
             "1 thread each, both engines of a channel at once." % (
                 meta["cpu"], meta["loadavg"], meta["budget"], meta["seed"]))
    if meta.get("lgp_config_json"):
        L.append("lgp config patch (`--config-json`): %s." % code_span(json.dumps(
            meta["lgp_config_json"], separators=(",", ":"))))
    L.append("")
    L.append("| channel | lgp RMS | lgp RMS (f64) | lgp largest cost | lgp gens / evals "
             "| Operon RMS | Operon RMS (f64) | Operon length | Operon RMS, length <= %d (length) "
             "| Operon gens / evals |" % OPERON_SHORT)
    L.append("|---|---|---|---|---|---|---|---|---|---|")
    for x in results:
        g, o = x["lgp"], x["operon"]
        L.append("| %s | %s | %s | %s | %s / %s | %s | %s | %s | %s (%s) | %s / %s |" % (
            x["channel"], fmt(g["best_rms_float32"]), fmt(g["best_rms_double"]),
            fmt(g["largest_cost"], "g"), g["generations"], g["evaluations"],
            fmt(o["best_rms"]), fmt(o["best_rms_double"]), o["best_length"],
            fmt(o["short_rms"]), o["short_length"] if o["short_length"] is not None else "-",
            o["generations"], o["evaluations"]))
    L += ["", "RMS over the 4096 table rows. lgp: the lowest `error` of its front (the float32 "
          "RMS, as the search scored it; `error_metric` is rmse) and that member's RMS from lgp's "
          "double-precision reference evaluator. Operon: sqrt(nmse_train * var(y)) of its front "
          "member of lowest NMSE (float32 predictions, population variance of y), and that "
          "model re-evaluated here from its printed formula in double precision. Both engines "
          "fit a linear scaling a*f + b.", ""]
    L.append("| channel | engine | wall s | CPU s | search s | front size | best member |")
    L.append("|---|---|---|---|---|---|---|")
    for x in results:
        g, o = x["lgp"], x["operon"]
        L.append("| %s | lgp | %.1f | %.1f | %.1f | %d | cost %s: %s |" % (
            x["channel"], g["wall_s"], g["cpu_s"], g["search_s"], g["members"],
            fmt(g["best_cost"], "g"), code_span(g["best_formula"])))
        L.append("| %s | Operon | %.1f | %.1f | %s | %d | length %d: %s |" % (
            x["channel"], o["wall_s"], o["cpu_s"], fmt(o["search_s"], ".1f"), o["members"],
            o["best_length"], code_span(o["best_model"])))
    busy = [(x["channel"], e, r["cpu_s"] / r["wall_s"]) for x in results
            for e, r in (("lgp", x["lgp"]), ("Operon", x["operon"]))
            if r["cpu_s"] < 0.8 * r["wall_s"]]
    if busy:  # wall budgets compare engines only when each had its core
        L += ["", "**Warning: the machine was busy.** CPU time / wall time: " + ", ".join(
            "%s %s %.0f %%" % (c, e, 100 * f) for c, e, f in busy) + ". Rerun on an idle machine."]
    L += ["", "Commands:", "", "```sh", shlex.join(meta["table_command"])]
    for x in results:
        L += ["# %s (started together)" % x["channel"]] + x["commands"]
    L += ["```", ""]
    return "\n".join(L)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", required=True, help="output directory")
    ap.add_argument("--budget", type=float, default=120.0, help="wall seconds per engine")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--quick", action="store_true", help="a 10 s budget, for testing")
    ap.add_argument("--lgp", default=os.environ.get(
        "LGP", os.path.join(REPO, "build", "release", "frontends", "lgp")))
    ap.add_argument("--operon", default=os.environ.get("OPERON_NSGP"),
                    help="operon_nsgp (default $OPERON_NSGP)")
    ap.add_argument("--channels", default=",".join(c[0] for c in CHANNELS),
                    help="comma list of channel names")
    ap.add_argument("--config-json", default="",
                    help="JSON merge patch for lgp's config, inline or @file, e.g. "
                         "'{\"program\":{\"constants\":16}}'")
    args = ap.parse_args()
    args.config_patch = {}
    if args.config_json:
        text = args.config_json
        try:
            if text.startswith("@"):
                with open(text[1:]) as f:
                    text = f.read()
            args.config_patch = json.loads(text)
        except (OSError, ValueError) as e:
            ap.error("--config-json: %s" % e)
        if not isinstance(args.config_patch, dict):
            ap.error("--config-json: must be a JSON object")
    if args.quick:
        args.budget = 10.0
    if args.budget <= 0:
        ap.error("--budget must be positive")
    if args.budget == int(args.budget):
        args.budget = int(args.budget)
    if not args.operon or not os.access(args.operon, os.X_OK):
        ap.error("operon_nsgp not found: give --operon PATH or set OPERON_NSGP")
    if not os.access(args.lgp, os.X_OK):
        ap.error("%s not found: build the lgp target, or give --lgp PATH" % args.lgp)
    args.lgp, args.operon = os.path.abspath(args.lgp), os.path.abspath(args.operon)
    wanted = args.channels.split(",")
    unknown = set(wanted) - {c[0] for c in CHANNELS}
    if unknown:
        ap.error("unknown channel(s) %s" % ",".join(sorted(unknown)))
    out = os.path.abspath(args.out)
    os.makedirs(out, exist_ok=True)

    meta = {"cpu": cpu_model(), "loadavg": " ".join("%.2f" % v for v in os.getloadavg()),
            "budget": args.budget, "seed": args.seed,
            "started": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            "lgp_config_json": args.config_patch}
    print("CPU: %s; load average %s" % (meta["cpu"], meta["loadavg"]), flush=True)
    meta["table_command"], rows = make_table(args.lgp, out)
    results = [run_channel(args, n, s, w, rows, out) for n, s, w in CHANNELS if n in wanted]
    text = report(meta, results)
    with open(os.path.join(out, "report.md"), "w") as f:
        f.write(text)
    with open(os.path.join(out, "results.json"), "w") as f:
        json.dump({"meta": meta, "channels": results}, f, indent=2)
        f.write("\n")
    print(text)


if __name__ == "__main__":
    main()
