#!/usr/bin/env python3
"""lgp next to Operon on any table, judged in measured GPU instructions on held-out rows.

For each table (a scene or a CSV; the DFG channels and the bench/quality tables by name) and
seed, one output at a time: starts `lgp run` and Operon's `operon_nsgp` together, one thread
each, with the same wall budget and seed; compiles every member of both final fronts to RDNA2
ISA through lgp's own backend (Operon's infix models translated into lgp's formula grammar and
scored with `lgp score --each`), scores every member in float32 on a held-out grid neither
engine trained on, and reports the best held-out RMS and max |error| at ISA <= k per engine and
their ratio (markdown in DIR/report.md, everything in DIR/results.json).

    python3 bench/peer/run.py --out DIR [--tables dfg_f0_1,dfg_f0_0p04,zh,normalization,energy]
        [--seeds 1,2] [--budget 300] [--quick] [--operon PATH] [--lgp PATH]
    python3 bench/peer/run.py --out DIR --table scene.json --inputs mu,r --output E
    python3 bench/peer/run.py --out DIR --table t.csv --holdout h.csv --inputs x,y --output f

Operon comes from --operon or $OPERON_NSGP; it is a peer measured against, never a dependency.
bench/peer/README.md gives the protocol and says how each figure is computed.
"""
import argparse
import copy
import csv
import glob
import hashlib
import json
import math
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
DFG_SCENE = os.path.join(REPO, "examples", "scenes", "dfg_64.json")
QUALITY_SPEC = os.path.join(REPO, "bench", "quality", "quality.json")
OPERON_SYMBOLS = "add,sub,mul,div,exp,log,sqrt,pow,square,fmin,fmax,abs"
KS = (8, 10, 12, 15, 20, 25, 30, 40, 50, 64)
FAMILY = "rdna2"  # the measured cost the tables are in
# The translation check: lgp's double-precision RMS of a translated Operon model on the training
# rows against Operon's own (float32) training RMS, within CHECK_REL relative plus CHECK_ULPS
# float32 ulps (2^-23) of the training output's largest |y| (Operon's float32 rounding).
CHECK_REL, CHECK_ULPS = 1e-3, 1.0


def cpu_model():
    try:
        with open("/proc/cpuinfo") as f:
            names = [l.split(":", 1)[1].strip() for l in f if l.startswith("model name")]
        if names:
            return "%s (%d logical CPUs)" % (names[0], len(names))
    except OSError:
        pass
    return "unknown"


def fmt(x, spec=".3g"):
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else format(x, spec)


def finite(x):
    return x is not None and isinstance(x, (int, float)) and math.isfinite(x)


# --- tables -----------------------------------------------------------------------------------
# A run is one table and one output: {"name", "title", "scene" or "csv" (+ "holdout"), "inputs",
# "weights": {column: weight}} (the output y = sum of weight * column).


def dfg_channel(name, title, weight_a):
    return {"name": name, "title": title, "scene": DFG_SCENE, "inputs": ["mu", "r"],
            "weights": {"A": weight_a, "B": 1.0}}


def quality_runs(table_name):
    """One run per output of a bench/quality table (its config's scene, inputs and outputs)."""
    with open(QUALITY_SPEC) as f:
        spec = json.load(f)
    entry = next((t for t in spec["tables"] if t["name"] == table_name), None)
    if entry is None:
        return None
    cfg_path = os.path.join(os.path.dirname(QUALITY_SPEC), entry["config"])
    with open(cfg_path) as f:
        cfg = json.load(f)
    data = cfg["data"]
    scene = os.path.normpath(os.path.join(os.path.dirname(cfg_path), data["scene"]))
    outs = data["outputs"]
    return [{"name": table_name if len(outs) == 1 else "%s_%s" % (table_name, o),
             "title": "%s: %s" % (table_name, o), "scene": scene, "inputs": data["inputs"],
             "weights": {o: 1.0}} for o in outs]


def named_runs(name):
    if name == "dfg_f0_1":
        return [dfg_channel(name, "DFG, F0 = 1 (A + B)", 1.0)]
    if name == "dfg_f0_0p04":
        return [dfg_channel(name, "DFG, F0 = 0.04 (0.04 A + B)", 0.04)]
    if name == "dfg":  # bench/quality's dfg table is its two channels
        return named_runs("dfg_f0_1") + named_runs("dfg_f0_0p04")
    return quality_runs(name)


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        sys.exit("error: %s: no rows" % path)
    return rows


def generate_scene_table(lgp, scene, path, commands):
    """`lgp data SCENE -o PATH --csv`; returns its rows and the grid values it used."""
    cmd = [lgp, "data", scene, "-o", path, "--csv", "-q"]
    commands.append(shlex.join(cmd))
    subprocess.run(cmd, check=True)
    with open(path + ".meta.json") as f:
        meta = json.load(f)
    meta = meta.get("meta", meta)
    return read_csv(path), meta["grid"]


def heldout_scene(scene, grid, inputs, functional):
    """The scene with every grid axis replaced by the midpoints of consecutive training values:
    cell centres against an edge-spaced axis (n - 1 of them), the points half-way between the
    centres of a cell-spaced axis. An axis that is no input of the run keeps its first value when
    the training table is a function of the inputs (its value then does not matter), else its
    midpoints too. An axis with one value keeps it."""
    out = copy.deepcopy(scene)
    out["name"] = scene.get("name", "scene") + "-heldout"
    out["description"] = ("held-out grid of bench/peer: midpoints of consecutive training grid "
                          "values on every axis")
    g = {}
    for axis in scene["grid"]:
        vals = sorted(float(v) for v in grid[axis]["values"])
        if axis not in inputs and functional:
            g[axis] = {"values": vals[:1]}
        elif len(vals) < 2:
            g[axis] = {"values": vals}
        else:
            g[axis] = {"values": midpoints(vals)}
    out["grid"] = g
    return out


def midpoints(vals):
    return [0.5 * (a + b) for a, b in zip(vals, vals[1:])]


def channel_rows(rows, inputs, weights, where):
    """(inputs as text, y as float) per row, y = sum weight * column."""
    missing = [c for c in list(inputs) + list(weights) if c not in rows[0]]
    if missing:
        sys.exit("error: %s: no column %s (columns: %s)" % (where, ", ".join(missing),
                                                            ", ".join(rows[0])))
    return [([r[c] for c in inputs], sum(w * float(r[c]) for c, w in weights.items()))
            for r in rows]


def is_function(rows):
    """Whether equal inputs always carry equal outputs."""
    seen = {}
    for x, y in rows:
        if seen.setdefault(tuple(x), y) != y:
            return False
    return True


def dedupe(rows):
    """Rows kept once when every distinct row repeats equally often (RMS and max unchanged);
    else the rows as they are. Returns (rows, copies)."""
    counts = {}
    for x, y in rows:
        key = (tuple(x), y)
        counts[key] = counts.get(key, 0) + 1
    copies = set(counts.values())
    if len(copies) != 1 or copies == {1}:
        return rows, 1
    seen, out = set(), []
    for x, y in rows:
        key = (tuple(x), y)
        if key not in seen:
            seen.add(key)
            out.append((x, y))
    return out, copies.pop()


def write_rows(path, inputs, rows):
    with open(path, "w") as f:
        f.write(",".join(list(inputs) + ["y"]) + "\n")
        for x, y in rows:
            f.write(",".join(x) + ",%r\n" % y)


def file_sha256(path):
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def prepare_data(lgp, run, d):
    """Writes d/train.csv and d/heldout.csv (inputs..., y); returns a description."""
    commands, inputs = [], run["inputs"]
    info = {"inputs": inputs, "weights": run["weights"], "commands": commands}
    if "scene" in run:
        with open(run["scene"]) as f:
            scene = json.load(f)
        if not isinstance(scene, dict) or scene.get("format") != "lgp-scene/1":
            sys.exit("error: %s: not a scene (format lgp-scene/1); give a scene, or a CSV table "
                     "(lgp data --csv) with --holdout" % run["scene"])
        full, grid = generate_scene_table(lgp, run["scene"], os.path.join(d, "scene-table.csv"),
                                          commands)
        rows = channel_rows(full, inputs, run["weights"], run["scene"])
        functional = is_function(rows)
        hs = heldout_scene(scene, grid, inputs, functional)
        hs_path = os.path.join(d, "heldout-scene.json")
        with open(hs_path, "w") as f:
            json.dump(hs, f, indent=1)
            f.write("\n")
        hfull, hgrid = generate_scene_table(lgp, hs_path, os.path.join(d, "heldout-table.csv"),
                                            commands)
        held = channel_rows(hfull, inputs, run["weights"], hs_path)
        info.update(scene=run["scene"], heldout_scene=hs_path, functional=functional,
                    train_grid={a: len(grid[a]["values"]) for a in scene["grid"]},
                    heldout_grid={a: hs["grid"][a]["values"] for a in hs["grid"]})
    else:
        rows = channel_rows(read_csv(run["csv"]), inputs, run["weights"], run["csv"])
        held = channel_rows(read_csv(run["holdout"]), inputs, run["weights"], run["holdout"])
        info.update(csv=run["csv"], holdout=run["holdout"])
    rows, copies = dedupe(rows)
    held, hcopies = dedupe(held)
    train_keys = {tuple(float(v) for v in x) for x, _ in rows}
    overlap = sum(1 for x, _ in held if tuple(float(v) for v in x) in train_keys)
    write_rows(os.path.join(d, "train.csv"), inputs, rows)
    write_rows(os.path.join(d, "heldout.csv"), inputs, held)
    info.update(train_rows=len(rows), train_copies=copies, heldout_rows=len(held),
                heldout_copies=hcopies, heldout_in_train=overlap,
                var_train=population_variance([y for _, y in rows]),
                var_heldout=population_variance([y for _, y in held]),
                train_sha256=file_sha256(os.path.join(d, "train.csv")),
                heldout_sha256=file_sha256(os.path.join(d, "heldout.csv")))
    # Operon reads one file: the training rows, then the held-out rows as its test range
    # (reported by Operon, never trained on).
    with open(os.path.join(d, "operon-data.csv"), "w") as f:
        f.write(",".join(list(inputs) + ["y"]) + "\n")
        for x, y in rows + held:
            f.write(",".join(x) + ",%r\n" % y)
    return info


def population_variance(y):
    m = sum(y) / len(y)
    return sum((v - m) ** 2 for v in y) / len(y)


# --- Operon's infix models --------------------------------------------------------------------
# operon_nsgp's InfixFormatter parenthesises every operation: numbers (negative ones as (-c)),
# weighted variables (c * x), (a op b [op c ...]) with + - * /, (a ^ b) for pow and (a ^ 2) for
# square, (-a), (1 / a), and f(a) or min/max(a, b). Parsed into a tree of tuples:
# ("num", text), ("var", name), ("neg", a), ("bin", op, a, b), ("call", name, [args]).

_TOKEN = re.compile(r"\s*(?:(\d+\.?\d*(?:[eE][-+]?\d+)?|\.\d+(?:[eE][-+]?\d+)?)|"
                    r"([A-Za-z_][A-Za-z_0-9]*)|(\S))")


def tokens(text):
    toks, pos, text = [], 0, text.strip()
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if m is None or m.end() == pos:
            raise ValueError("cannot read %r" % text[pos:pos + 20])
        pos = m.end()
        num, name, op = m.groups()
        toks.append(("num", num) if num else ("name", name) if name else ("op", op))
    return toks


def parse_operon(text):
    """Operon's infix model as a tree; raises ValueError when the text is not understood."""
    toks, pos = tokens(text), [0]

    def peek():
        return toks[pos[0]] if pos[0] < len(toks) else ("end", None)

    def take(kind=None, value=None):
        t = peek()
        if (kind and t[0] != kind) or (value is not None and t[1] != value):
            raise ValueError("expected %s at token %d of %r" % (value or kind, pos[0], text[:60]))
        pos[0] += 1
        return t

    def level(ops, sub):
        def parse():
            left = sub()
            while peek()[0] == "op" and peek()[1] in ops:
                op = take()[1]
                left = ("bin", op, left, sub())
            return left
        return parse

    def unary():
        if peek() == ("op", "-"):
            take()
            return ("neg", unary())
        return primary()

    def primary():
        kind, val = take()
        if kind == "num":
            return ("num", val)
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
                return ("call", val, args)
            return ("var", val)
        raise ValueError("unexpected %r in %r" % (val, text[:60]))

    power = level("^", unary)
    term = level("*/", power)
    expr = level("+-", term)
    tree = expr()
    if pos[0] != len(toks):
        raise ValueError("trailing text at token %d of %r" % (pos[0], text[:60]))
    return tree


# Operon function -> lgp op of the same meaning (lgp/core/ops.hpp), with its arity.
_LGP_FUNCS = {"exp": ("exp", 1), "log": ("log", 1), "sqrt": ("sqrt", 1), "abs": ("abs", 1),
              "square": ("square", 1), "sin": ("sin", 1), "cos": ("cos", 1),
              "min": ("min", 2), "fmin": ("min", 2), "max": ("max", 2), "fmax": ("max", 2),
              "pow": ("pow", 2)}


def to_lgp(tree, inputs):
    """The tree in lgp's formula grammar (emit/README.md): every operation parenthesised, `^`
    as pow(a, b) except an exponent of exactly 2 (Operon's square) as square(a), literals as
    Operon printed them (lgp rounds them to float32, which is what they were)."""
    kind = tree[0]
    if kind == "num":
        return tree[1]
    if kind == "var":
        if tree[1] not in inputs:
            raise ValueError("unknown variable %r" % tree[1])
        return tree[1]
    if kind == "neg":
        return "(-%s)" % to_lgp(tree[1], inputs)
    if kind == "bin":
        _, op, a, b = tree
        if op == "^":
            if b[0] == "num" and float(b[1]) == 2.0:
                return "square(%s)" % to_lgp(a, inputs)
            return "pow(%s, %s)" % (to_lgp(a, inputs), to_lgp(b, inputs))
        return "(%s %s %s)" % (to_lgp(a, inputs), op, to_lgp(b, inputs))
    name, args = tree[1], tree[2]
    if name not in _LGP_FUNCS or _LGP_FUNCS[name][1] != len(args):
        raise ValueError("no lgp operator for %s with %d arguments" % (name, len(args)))
    return "%s(%s)" % (_LGP_FUNCS[name][0], ", ".join(to_lgp(a, inputs) for a in args))


def translate(model, inputs, output="y"):
    """Operon's infix model as an lgp formula `y = ...`; raises ValueError."""
    return "%s = %s" % (output, to_lgp(parse_operon(model), inputs))


# The same tree evaluated in double precision with Operon's (IEEE, unprotected) semantics: an
# evaluation independent of lgp, for the report.


def _div(a, b):
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


def _fmin(a, b):
    return b if math.isnan(a) else a if math.isnan(b) else min(a, b)


def _fmax(a, b):
    return b if math.isnan(a) else a if math.isnan(b) else max(a, b)


_PY_FUNCS = {"exp": _guard(math.exp), "log": _guard(math.log), "sqrt": _guard(math.sqrt),
             "abs": abs, "square": lambda a: a * a, "sin": math.sin, "cos": math.cos,
             "min": _fmin, "fmin": _fmin, "max": _fmax, "fmax": _fmax, "pow": _guard(math.pow)}


def to_python(tree, inputs):
    kind = tree[0]
    if kind == "num":
        return repr(float(tree[1]))
    if kind == "var":
        return "v[%d]" % inputs.index(tree[1])
    if kind == "neg":
        return "(-%s)" % to_python(tree[1], inputs)
    if kind == "bin":
        _, op, a, b = tree
        a, b = to_python(a, inputs), to_python(b, inputs)
        if op == "/":
            return "_div(%s, %s)" % (a, b)
        if op == "^":
            return "F['pow'](%s, %s)" % (a, b)
        return "(%s %s %s)" % (a, op, b)
    return "F[%r](%s)" % (tree[1], ", ".join(to_python(a, inputs) for a in tree[2]))


def operon_function(model, inputs):
    """A Python function of a list of input values (Operon's semantics, double precision)."""
    src = "lambda v: " + to_python(parse_operon(model), inputs)
    return eval(src, {"_div": _div, "F": _PY_FUNCS, "inf": math.inf, "nan": math.nan})


def rms_max(f, rows):
    """RMS and max |error| of f over (x, y) rows; NaN when any prediction is not finite."""
    s, worst = 0.0, 0.0
    for x, y in rows:
        try:
            p = f(x)
        except (OverflowError, ValueError, ZeroDivisionError):
            return math.nan, math.nan
        if not math.isfinite(p):
            return math.nan, math.nan
        s += (p - y) * (p - y)
        worst = max(worst, abs(p - y))
    return math.sqrt(s / len(rows)), worst


def load_rows(path, inputs):
    return [([float(r[c]) for c in inputs], float(r["y"])) for r in read_csv(path)]


# --- scoring through lgp ----------------------------------------------------------------------


def lgp_score_each(lgp, table, inputs, formulas, path, measure, commands):
    """`lgp score TABLE --each --json` on one formula per line; one result per formula."""
    with open(path, "w") as f:
        for t in formulas:
            if "\n" in t:
                raise ValueError("a formula with a newline: %r" % t[:60])
            f.write(t + "\n")
    cmd = [lgp, "score", table, "--inputs", ",".join(inputs), "--outputs", "y", "--each",
           "--expr-file", path, "--json"] + ([] if measure else ["--no-measure"])
    commands.append(shlex.join(cmd))
    if not formulas:
        return []
    out = subprocess.run(cmd, check=True, stdout=subprocess.PIPE, text=True).stdout
    res = json.loads(out)
    if len(res) != len(formulas):
        sys.exit("error: lgp score --each gave %d results for %d formulas" % (len(res),
                                                                              len(formulas)))
    return res


def metric(r, path, key):
    """outputs[0][path][key] of an lgp score result, None where it failed or is not finite."""
    if r.get("failed"):
        return None
    v = r["outputs"][0][path][key]
    return v if finite(v) else None


def isa_of(cost_measured):
    try:
        v = cost_measured[FAMILY]["instructions"]
    except (KeyError, TypeError):
        return None
    return v if finite(v) else None


# --- the two engines --------------------------------------------------------------------------


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


def lgp_config(inputs, budget, seed, patch=None):
    cfg = {
        "data": {"path": "../train.csv", "inputs": list(inputs), "outputs": ["y"]},
        "objectives": {"error": "rmse"},
        "search": {"linear_scaling": True, "threads": 1, "wall_time_s": budget,
                   "generations": 0, "seed": seed},
        "output": {"front_json": "lgp-front.json", "front_csv": "lgp-front.csv"},
    }
    # The protocol keys (budget, thread, seed, files) always win over the patch.
    fixed = {"search": {k: cfg["search"][k] for k in ("threads", "wall_time_s", "generations",
                                                       "seed")},
             "data": cfg["data"], "output": cfg["output"]}
    return merge_patch(merge_patch(cfg, patch or {}), fixed)


def operon_args(exe, inputs, train_rows, heldout_rows, budget, seed):
    return [exe, "--dataset", "../operon-data.csv", "--target", "y", "--inputs", ",".join(inputs),
            "--train", "0:%d" % train_rows,
            "--test", "%d:%d" % (train_rows, train_rows + heldout_rows),
            "--population-size", "1000", "--pool-size", "1000",
            "--generations", "100000", "--evaluations", "1000000000",
            "--iterations", "5", "--timelimit", str(budget), "--threads", "1",
            "--seed", str(seed), "--enable-symbols", OPERON_SYMBOLS]


def run_together(jobs, deadline_s):
    """Starts every job at once; waits for all. Returns per job (exit code, wall s, cpu s,
    killed)."""
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
    # wait4 on each of ours gives the child's own CPU time and (polled) its end time; never on
    # any child, since other threads (--jobs) have children of their own.
    while len(result) < len(procs):
        for p in procs:
            if p.pid in result:
                continue
            pid, status, usage = os.wait4(p.pid, os.WNOHANG)
            if pid == p.pid:
                p.returncode = os.waitstatus_to_exitcode(status)
                result[pid] = (p.returncode, time.monotonic() - t0[pid],
                               usage.ru_utime + usage.ru_stime, pid in killed)
        if len(result) < len(procs):
            time.sleep(0.02)
    timer.cancel()
    return [result[p.pid] for p in procs]


def operon_log(stdout_path):
    """The last generation row of operon_nsgp's log: generations, evaluations, elapsed."""
    last, header = None, None
    with open(stdout_path) as f:
        lines = f.read().splitlines()
    header = next((l.split() for l in lines if l.startswith("iteration")), None)
    for l in lines:
        w = l.split()
        if header and len(w) == len(header) and re.fullmatch(r"\d+", w[0]):
            last = dict(zip(header, w))
    if not last:
        return {"generations": None, "evaluations": None, "search_s": None}
    return {"generations": int(last["iteration"]) + 1, "evaluations": int(last["eval_cnt"]),
            "search_s": float(last["elapsed"])}


def read_operon_front(path, var_train, var_heldout):
    members, dropped = [], 0
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            nmse, nmse_te = float(row["nmse_train"]), float(row["nmse_test"])
            if not math.isfinite(nmse):
                dropped += 1
                continue
            members.append({
                "length": int(row["length"]), "model": row["model"],
                "train_rms_operon": math.sqrt(nmse * var_train) if nmse >= 0 else math.nan,
                "heldout_rms_operon": (math.sqrt(nmse_te * var_heldout)
                                       if math.isfinite(nmse_te) and nmse_te >= 0 else None)})
    return members, dropped


def check_ok(lgp_double, operon_rms, y_scale):
    return (finite(lgp_double) and finite(operon_rms)
            and abs(lgp_double - operon_rms)
            <= CHECK_REL * operon_rms + CHECK_ULPS * 2.0 ** -23 * y_scale)


def score_operon(args, members, inputs, data_dir, d, train_rows, commands):
    """Translates, measures and scores every Operon member; fills the member dicts."""
    formulas, idx = [], []
    for i, m in enumerate(members):
        try:
            m["formula"] = translate(m["model"], inputs)
            formulas.append(m["formula"])
            idx.append(i)
        except ValueError as e:
            m["formula"], m["failed"] = None, "translation: %s" % e
    train = lgp_score_each(args.lgp, os.path.join(data_dir, "train.csv"), inputs, formulas,
                           os.path.join(d, "operon-formulas.txt"), True, commands)
    held = lgp_score_each(args.lgp, os.path.join(data_dir, "heldout.csv"), inputs, formulas,
                          os.path.join(d, "operon-formulas.txt"), False, commands)
    for i, tr, he in zip(idx, train, held):
        m = members[i]
        if tr.get("failed"):
            m["failed"] = "lgp score: %s" % tr["failed"]
            continue
        m["isa"] = isa_of(tr.get("cost_measured"))
        m["train_rms_f64"] = metric(tr, "double", "rmse")
        m["train_rms_f32"] = metric(tr, "float32", "rmse")
        m["heldout_rms"] = metric(he, "float32", "rmse")
        m["heldout_max"] = metric(he, "float32", "max_abs")
        m["check"] = check_ok(m["train_rms_f64"], m["train_rms_operon"],
                              max(abs(y) for _, y in train_rows))
    for m in members:  # Operon's own semantics in double, independently of lgp
        try:
            m["train_rms_python_f64"] = rms_max(operon_function(m["model"], inputs), train_rows)[0]
        except (ValueError, SyntaxError, RecursionError):
            m["train_rms_python_f64"] = None


def score_lgp(args, front_path, inputs, data_dir, d, commands):
    with open(front_path) as f:
        front = json.load(f)
    if front.get("error_metric") != "rmse" or front.get("error_channels") != ["y"]:
        sys.exit("error: %s: expected error_metric rmse on output y" % front_path)
    info = front.get("cost_measured_info", {})
    if "unavailable" in info:
        sys.exit("error: %s: no measured cost (%s); the benchmark needs the ISA backend "
                 "(LGP_WITH_GPU and Mesa's RADV)" % (front_path, info["unavailable"]))
    members = []
    for m in front["members"]:
        o = m["outputs"][0]
        members.append({"index": m.get("index"), "formula": m["formula"], "cost": m["cost"],
                        "isa": isa_of(m.get("cost_measured")),
                        "train_rms_f32": o["float32"]["rmse"], "train_rms_f64": o["double"]["rmse"]})
    formulas = [m["formula"] for m in members]
    train = lgp_score_each(args.lgp, os.path.join(data_dir, "train.csv"), inputs, formulas,
                           os.path.join(d, "lgp-formulas.txt"), False, commands)
    held = lgp_score_each(args.lgp, os.path.join(data_dir, "heldout.csv"), inputs, formulas,
                          os.path.join(d, "lgp-formulas.txt"), False, commands)
    for m, tr, he in zip(members, train, held):
        if tr.get("failed") or he.get("failed"):
            m["failed"] = "lgp score: %s" % (tr.get("failed") or he.get("failed"))
            continue
        m["formula_train_rms_f32"] = metric(tr, "float32", "rmse")
        m["heldout_rms"] = metric(he, "float32", "rmse")
        m["heldout_max"] = metric(he, "float32", "max_abs")
        # The printed formula (what is exported and measured) reproduces the scored program?
        a, b = m["formula_train_rms_f32"], m["train_rms_f32"]
        m["formula_matches"] = finite(a) and finite(b) and abs(a - b) <= 1e-3 * b + 1e-7
    p = front["progress"]
    return members, {"generations": p.get("generation"), "evaluations": p.get("evaluations"),
                     "search_s": p.get("elapsed_s"), "stop_reason": p.get("stop_reason")}


def snapshot_files(d):
    """lgp run --front-every's fronts in run folder d, in time order."""
    return sorted(glob.glob(os.path.join(d, "lgp-front.at*s.json")))


def score_snapshots(args, d, inputs, data_dir, commands):
    """Every snapshot front measured and scored on the held-out rows: per snapshot its search
    time and the best held-out RMS at ISA <= k (lgp score measures each formula's ISA)."""
    out = []
    for i, path in enumerate(snapshot_files(d)):
        with open(path) as f:
            front = json.load(f)
        formulas = [m["formula"] for m in front["members"]]
        cmds = []
        held = lgp_score_each(args.lgp, os.path.join(data_dir, "heldout.csv"), inputs, formulas,
                              os.path.join(d, "snapshot-formulas.txt"), True, cmds)
        if i == 0:
            commands.append("# every snapshot (%s ...): %s" % (os.path.basename(path), cmds[0]))
        members = [{"isa": isa_of(h.get("cost_measured")),
                    "heldout_rms": metric(h, "float32", "rmse"),
                    "heldout_max": metric(h, "float32", "max_abs")}
                   for h in held if not h.get("failed")]
        out.append({"file": os.path.basename(path), "search_s": front["progress"]["elapsed_s"],
                    "rms": {k: v["rms"] for k, v in per_k(members).items()}})
    return out


def time_to_operon(snaps, final_k, final_s, op_k):
    """Per k, the first search time (a snapshot's, or the final front's) at which lgp's best
    held-out RMS at ISA <= k is at or below Operon's final figure; None when it never is (or
    there were no snapshots)."""
    if not snaps:
        return None
    points = [(s["search_s"], s["rms"]) for s in snaps]
    points.append((final_s, {k: v["rms"] for k, v in final_k.items()}))
    out = {}
    for k in final_k:
        target = op_k[k]["rms"]
        out[k] = next((t for t, rms in points if finite(target) and finite(rms.get(k))
                       and rms[k] <= target), None)
    return out


def usable(m):
    """Measured, with finite held-out figures. An Operon member that fails the translation check
    stays: its figures are those of the translated formula, a shader with that cost and error
    (the report lists it, and marks a per-k figure that comes from it)."""
    return (not m.get("failed") and m.get("isa") is not None and finite(m.get("heldout_rms"))
            and finite(m.get("heldout_max")))


def per_k(members):
    """Best held-out RMS and best held-out max |error| (each minimised on its own) over the
    usable members of at most k measured instructions, for every k of KS; *_unchecked: the
    figure comes from a member that failed the translation check."""
    ok = [m for m in members if usable(m)]
    out = {}
    for k in KS:
        c = [m for m in ok if m["isa"] <= k]
        row = {}
        for key, field in (("rms", "heldout_rms"), ("max", "heldout_max")):
            best = min(c, key=lambda m: m[field], default=None)
            row[key] = best[field] if best else None
            row[key + "_unchecked"] = bool(best) and best.get("check") is False
        out[str(k)] = row
    return out


def ratio(a, b):
    return a / b if finite(a) and finite(b) and b > 0 else None


def run_one(args, run, seed, data_dir, data):
    d = os.path.join(data_dir, "seed%d" % seed)
    os.makedirs(d, exist_ok=True)
    inputs = run["inputs"]
    cfg_path = os.path.join(d, "lgp.json")
    with open(cfg_path, "w") as f:
        json.dump(lgp_config(inputs, args.budget, seed, args.config_patch), f, indent=2)
        f.write("\n")
    jobs = [
        {"argv": [args.lgp, "run", "lgp.json"] + (
            ["--front-every", "%g" % args.snapshots] if args.snapshots else []), "env": {},
         "cwd": d,
         "stdout": os.path.join(d, "lgp.out"), "stderr": os.path.join(d, "lgp.err")},
        {"argv": operon_args(args.operon, inputs, data["train_rows"], data["heldout_rows"],
                             args.budget, seed),
         "env": {"OPERON_PARETO_FRONT": "operon-front.csv"}, "cwd": d,
         "stdout": os.path.join(d, "operon.out"), "stderr": os.path.join(d, "operon.err")},
    ]
    commands = ["(cd %s && %s%s)" % (shlex.quote(j["cwd"]),
                                    "".join("%s=%s " % (k, shlex.quote(v))
                                            for k, v in j["env"].items()),
                                    shlex.join(j["argv"])) for j in jobs]
    engines_json = os.path.join(d, "engines.json")
    op_saved = None  # Operon's run from an earlier results.json, read once per run
    if args.reuse and os.path.exists(engines_json):
        print("[%s seed %d] reusing the fronts of %s" % (run["name"], seed, d), flush=True)
        with open(engines_json) as f:
            saved = json.load(f)
        (lrc, lwall, lcpu, lkill), (orc, owall, ocpu, okill) = saved["usage"]
        loadavg = saved.get("loadavg")
        commands = saved.get("commands", commands)
    else:
        for name in ["lgp-front.json", "operon-front.csv", "engines.json"] + [
                os.path.basename(p) for p in snapshot_files(d)]:
            if os.path.exists(os.path.join(d, name)):
                os.remove(os.path.join(d, name))
        saved = {}
        if args.operon_from:  # Operon's front and usage are the earlier run's; only lgp searches
            src = os.path.join(args.operon_from, run["name"], "seed%d" % seed)
            if os.path.exists(os.path.join(src, "engines.json")):
                try:
                    with open(os.path.join(src, "engines.json")) as f:
                        earlier = json.load(f)
                    for name in ("operon-front.csv", "operon.out", "operon.err"):
                        shutil.copyfile(os.path.join(src, name), os.path.join(d, name))
                except (OSError, ValueError) as e:
                    sys.exit("error: --operon-from: %s" % e)
            else:  # a committed output keeps only results.json: Operon's scored front is there
                src = os.path.join(args.operon_from, "results.json")
                earlier = op_saved = saved_operon_run(src, run["name"], seed)
                saved["operon_results"] = src
            jobs_run = jobs[:1]
            commands = commands[:1] + ["# Operon: %s" % c for c in earlier["commands"][1:]]
            saved["operon_from"] = src
            print("[%s seed %d] lgp alone, %g s (Operon's front from %s) ..." % (
                run["name"], seed, args.budget, src), flush=True)
        else:
            jobs_run = jobs
            print("[%s seed %d] lgp and Operon together, %g s each ..." % (
                run["name"], seed, args.budget), flush=True)
        loadavg = " ".join("%.2f" % v for v in os.getloadavg())
        usage = run_together(jobs_run, deadline_s=3 * args.budget + 300)
        for label, (rc, _, _, _), j in zip(("lgp", "operon"), usage, jobs_run):
            if rc != 0:
                sys.exit("error: %s exited %d; see %s" % (label, rc, j["stderr"]))
        if args.operon_from:
            usage.append(earlier["usage"][1])
        (lrc, lwall, lcpu, lkill), (orc, owall, ocpu, okill) = usage
        saved.update(usage=usage, loadavg=loadavg, commands=commands)
        with open(engines_json, "w") as f:
            json.dump(saved, f, indent=1)
            f.write("\n")
    score_cmds = []
    print("[%s seed %d] measuring and scoring both fronts ..." % (run["name"], seed), flush=True)
    lgp_members, lgp_prog = score_lgp(args, os.path.join(d, "lgp-front.json"), inputs,
                                      data_dir, d, score_cmds)
    if saved.get("operon_results"):  # measured and scored when that output was written
        op_saved = op_saved or saved_operon_run(saved["operon_results"], run["name"], seed)
        op = op_saved["operon"]
        op_members, dropped = op["members"], op["dropped_not_finite"]
        op_log = {k: op[k] for k in ("generations", "evaluations", "search_s")}
    else:
        op_members, dropped = read_operon_front(os.path.join(d, "operon-front.csv"),
                                                data["var_train"], data["var_heldout"])
        train_rows = load_rows(os.path.join(data_dir, "train.csv"), inputs)
        score_operon(args, op_members, inputs, data_dir, d, train_rows, score_cmds)
        op_log = operon_log(jobs[1]["stdout"])
    lgp_k, op_k = per_k(lgp_members), per_k(op_members)
    snaps = score_snapshots(args, d, inputs, data_dir, score_cmds)
    table = {k: {"lgp_rms": lgp_k[k]["rms"], "operon_rms": op_k[k]["rms"],
                 "rms_ratio": ratio(lgp_k[k]["rms"], op_k[k]["rms"]),
                 "lgp_max": lgp_k[k]["max"], "operon_max": op_k[k]["max"],
                 "max_ratio": ratio(lgp_k[k]["max"], op_k[k]["max"]),
                 "operon_rms_unchecked": op_k[k]["rms_unchecked"],
                 "operon_max_unchecked": op_k[k]["max_unchecked"]} for k in lgp_k}
    return {
        "table": run["name"], "title": run["title"], "seed": seed, "dir": d, "loadavg": loadavg,
        "commands": commands, "scoring_commands": score_cmds, "per_k": table,
        "lgp": dict(lgp_prog, wall_s=lwall, cpu_s=lcpu, killed=lkill, members=lgp_members),
        "snapshots": snaps,
        "time_to_operon": time_to_operon(snaps, lgp_k, lgp_prog.get("search_s"), op_k),
        "operon": dict(op_log, wall_s=owall, cpu_s=ocpu, killed=okill,
                       members=op_members, dropped_not_finite=dropped),
    }


# --- the report -------------------------------------------------------------------------------


def code_span(text):
    """A markdown code span that holds any text: a fence longer than its longest backtick run."""
    longest = max((len(m) for m in re.findall(r"`+", text)), default=0)
    pad = " " if longest else ""
    return "`" * (longest + 1) + pad + text + pad + "`" * (longest + 1)


def fmt_ratio(r):
    if r is None:
        return "-"
    s = "%.2g" % r if r < 0.1 else "%.2f" % r if r < 10 else "%.1f" % r
    return "**%s**" % s if r > 1 else s


def dagger(t, key):
    return " &dagger;" if t.get("operon_%s_unchecked" % key) else ""


def k_columns():
    """The per-k header cells of a markdown table: `k = 8 | 10 | ... | 64`."""
    return " | ".join("k = %d" % k if i == 0 else str(k) for i, k in enumerate(KS))


def ratio_table(results, key, L):
    L.append("| table | seed | " + k_columns() + " |")
    L.append("|---|---|" + "---|" * len(KS))
    for x in results:
        L.append("| %s | %d | %s |" % (x["title"], x["seed"], " | ".join(
            fmt_ratio(x["per_k"][str(k)][key + "_ratio"]) + dagger(x["per_k"][str(k)], key)
            for k in KS)))


def isa_range(members):
    v = [m["isa"] for m in members if usable(m)]
    return "%g-%g" % (min(v), max(v)) if v else "-"


def check_summary(members):
    tried = [m for m in members if m.get("train_rms_f64") is not None or m.get("failed")]
    ok = [m for m in members if m.get("check")]
    rel = [abs(m["train_rms_f64"] - m["train_rms_operon"]) / m["train_rms_operon"]
           for m in members if finite(m.get("train_rms_f64")) and finite(m.get("train_rms_operon"))
           and m["train_rms_operon"] > 0]
    return len(members), len(ok), max(rel) if rel else None, len(tried)


def report(meta, data_info, results):
    L = ["# lgp and Operon in measured GPU instructions, on held-out rows", ""]
    L.append("CPU: %s. Budget %g s wall per engine and output, 1 thread each, %s; seeds %s." % (
        meta["cpu"], meta["budget"], "lgp alone (below)" if meta.get("operon_from") else
        "both engines of a run started together", ", ".join(str(s) for s in meta["seeds"])))
    if meta.get("operon_from"):
        L.append("**Only lgp searched in this output**: Operon's fronts (and its figures below) "
                 "are those of the earlier runs in `$OPERON_FROM` (same tables, seeds, budget "
                 "and rows); lgp ran %d run(s) at a time, one thread each, so a run's companion "
                 "on the second core was %s." % (
                     meta["jobs"], "another lgp run" if meta["jobs"] > 1 else "nothing"))
    if meta.get("lgp_config_json"):
        L.append("lgp config patch (`--config-json`): %s." % code_span(json.dumps(
            meta["lgp_config_json"], separators=(",", ":"))))
    L += ["", "ISA = RDNA2 instructions of the member's `lgp emit --lang hlsl --fast` code over an "
          "I/O-only shader (ACO, RADV's null device); Operon's models translated into lgp's "
          "formula grammar. Errors are float32 on the held-out rows. Ratio lgp / Operon (below "
          "1: lgp better; bold: Operon better; -: an engine has no member at or below k; "
          "&dagger;: Operon's figure comes from a member that failed the translation check, "
          "i.e. from its translation, listed under its table).", ""]
    L += ["## Best held-out RMS at ISA <= k, lgp / Operon", ""]
    ratio_table(results, "rms", L)
    L += ["", "## Best held-out max |error| at ISA <= k, lgp / Operon", ""]
    ratio_table(results, "max", L)
    timed = [x for x in results if x.get("time_to_operon")]
    if timed:
        L += ["", "## Time to Operon's held-out RMS at ISA <= k", "",
              "lgp's search seconds until its best held-out RMS at ISA <= k first reached "
              "Operon's after Operon's whole budget (lgp's front written every %g s, so `<= t` "
              "is by the first snapshot; `-`: not within lgp's budget; n/a: Operon has no "
              "member at or below k)." %
              meta["snapshots"], "",
              "| table | seed | " + " | ".join(str(k) for k in KS) + " |",
              "|---|---|" + "---|" * len(KS)]
        for x in timed:
            cells = []
            first = x["snapshots"][0]["search_s"]
            for k in KS:
                t = x["time_to_operon"][str(k)]
                cells.append("n/a" if not finite(x["per_k"][str(k)]["operon_rms"]) else
                             "-" if t is None else ("<= %.0f" if t == first else "%.0f") % t)
            L.append("| %s | %d | %s |" % (x["title"], x["seed"], " | ".join(cells)))
    busy = [(x["title"], x["seed"], e, r["cpu_s"] / r["wall_s"]) for x in results
            for e, r in (("lgp", x["lgp"]), ("Operon", x["operon"]))
            if r["cpu_s"] < 0.8 * r["wall_s"]]
    if busy:
        L += ["", "**Warning: the machine was busy.** CPU time / wall time below 80 %: " +
              ", ".join("%s seed %d %s %.0f %%" % (t, s, e, 100 * f) for t, s, e, f in busy) +
              ". Budgets are wall time: rerun on an idle machine."]
    for x in results:
        di = data_info[x["table"]]
        g, o = x["lgp"], x["operon"]
        L += ["", "## %s, seed %d" % (x["title"], x["seed"]), ""]
        L.append(heldout_text(di))
        L += ["", "| ISA <= k | lgp RMS | Operon RMS | ratio | lgp max | Operon max | ratio |",
              "|---|---|---|---|---|---|---|"]
        for k in KS:
            t = x["per_k"][str(k)]
            L.append("| %d | %s | %s%s | %s | %s | %s%s | %s |" % (
                k, fmt(t["lgp_rms"], ".3e"), fmt(t["operon_rms"], ".3e"), dagger(t, "rms"),
                fmt_ratio(t["rms_ratio"]), fmt(t["lgp_max"], ".3e"), fmt(t["operon_max"], ".3e"),
                dagger(t, "max"), fmt_ratio(t["max_ratio"])))
        n, ok, worst, _ = check_summary(o["members"])
        mism = [m for m in g["members"] if m.get("formula_matches") is False]
        L += ["", "Load average when the engines started: %s." % (x.get("loadavg") or "-")]
        L += ["", "| engine | wall s | CPU s | search s | generations | evaluations | front "
              "(usable) | ISA range |", "|---|---|---|---|---|---|---|---|"]
        L.append("| lgp | %.1f | %.1f | %s | %s | %s | %d (%d) | %s |" % (
            g["wall_s"], g["cpu_s"], fmt(g["search_s"], ".1f"), g["generations"],
            g["evaluations"], len(g["members"]),
            sum(usable(m) for m in g["members"]), isa_range(g["members"])))
        L.append("| Operon | %.1f | %.1f | %s | %s | %s | %d (%d) | %s |" % (
            o["wall_s"], o["cpu_s"], fmt(o["search_s"], ".1f"), o["generations"],
            o["evaluations"], len(o["members"]),
            sum(usable(m) for m in o["members"]), isa_range(o["members"])))
        held = [abs(m["heldout_rms"] - m["heldout_rms_operon"]) / m["heldout_rms_operon"]
                for m in o["members"] if finite(m.get("heldout_rms"))
                and finite(m.get("heldout_rms_operon")) and m["heldout_rms_operon"] > 0]
        L += ["", "Translation check: %d of %d Operon members' double-precision training RMS "
              "through lgp is within %g relative (+ %g float32 ulp of max |y|) of Operon's own; "
              "largest relative difference %s. On the held-out rows (Operon's test range) lgp's "
              "float32 RMS of the translated members and Operon's own float32 RMS differ by at "
              "most %s (relative)." % (ok, n, CHECK_REL, CHECK_ULPS, fmt(worst, ".2e"),
                                       fmt(max(held) if held else None, ".2e"))]
        bad = [m for m in o["members"] if not m.get("check")]
        for m in bad:
            L.append("- failed: length %d, ISA %s, training RMS: Operon %s, lgp double %s, "
                     "Python double (Operon's semantics) %s; held-out RMS: Operon %s, "
                     "translation %s%s" % (
                         m["length"], fmt(m.get("isa"), "g"), fmt(m["train_rms_operon"], ".4e"),
                         fmt(m.get("train_rms_f64"), ".4e"),
                         fmt(m.get("train_rms_python_f64"), ".4e"),
                         fmt(m.get("heldout_rms_operon"), ".4e"), fmt(m.get("heldout_rms"), ".4e"),
                         "; " + m["failed"] if m.get("failed") else ""))
        if o["dropped_not_finite"]:
            L.append("- %d Operon members without a finite training NMSE left out." %
                     o["dropped_not_finite"])
        if mism:
            L.append("")
            L.append("%d lgp members' printed formula (what is exported and measured) does not "
                     "reproduce the training RMS the search scored (beyond 0.1 %%); their held-out "
                     "figures are the formula's: %s." % (len(mism), ", ".join(
                         "ISA %s scored %s, formula %s" % (fmt(m["isa"], "g"),
                                                           fmt(m["train_rms_f32"], ".3e"),
                                                           fmt(m["formula_train_rms_f32"], ".3e"))
                         for m in mism)))
    L += ["", "## Commands", "", "```sh", meta["command"]]
    for name, di in data_info.items():
        L += ["# %s: the tables" % name] + di["commands"]
    for x in results:
        L += ["# %s seed %d (started together)" % (x["table"], x["seed"])] + x["commands"]
        L += ["# scoring"] + x["scoring_commands"]
    L += ["```", ""]
    return "\n".join(L)


def heldout_text(di):
    if "scene" in di:
        g = ", ".join("%s %d -> %d%s" % (a, di["train_grid"][a], len(v),
                                          "" if a in di["inputs"] else " (no input)")
                      for a, v in di["heldout_grid"].items())
        s = ("Training: %d rows of the scene's grid; held-out: %d rows, the midpoints of "
             "consecutive training grid values on every axis (%s)" % (
                 di["train_rows"], di["heldout_rows"], g))
    else:
        s = "Training: %d rows of %s; held-out: %d rows of %s" % (
            di["train_rows"], os.path.basename(di["csv"]), di["heldout_rows"],
            os.path.basename(di["holdout"]))
    if di["train_copies"] > 1:
        s += "; the training table repeats every row %d times (an axis that is no input), kept " \
             "once" % di["train_copies"]
    s += "; %d held-out rows coincide with training rows." % di["heldout_in_train"]
    return s


# --- main -------------------------------------------------------------------------------------


def parse_args(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", required=True, help="output directory")
    ap.add_argument("--tables", default="",
                    help="named tables, comma-separated: dfg_f0_1, dfg_f0_0p04, dfg (both), and "
                         "the bench/quality tables (zh, normalization, energy); default "
                         "dfg_f0_1,dfg_f0_0p04 unless --table is given")
    ap.add_argument("--table", help="a scene JSON or a CSV table (then --holdout)")
    ap.add_argument("--holdout", help="held-out CSV for a CSV --table")
    ap.add_argument("--inputs", help="input columns of --table, comma-separated")
    ap.add_argument("--output", help="output column(s) of --table, comma-separated: one run each")
    ap.add_argument("--name", help="name of --table in the report (default: its file name)")
    ap.add_argument("--budget", type=float, default=300.0, help="wall seconds per engine and run")
    ap.add_argument("--seeds", default="1", help="comma-separated seeds")
    ap.add_argument("--quick", action="store_true", help="a 10 s budget, for testing")
    ap.add_argument("--lgp", default=os.environ.get(
        "LGP", os.path.join(REPO, "build", "release", "frontends", "lgp")))
    ap.add_argument("--operon", default=os.environ.get("OPERON_NSGP"),
                    help="operon_nsgp (default $OPERON_NSGP)")
    ap.add_argument("--config-json", default="",
                    help="JSON merge patch for lgp's config, inline or @file")
    ap.add_argument("--reuse", action="store_true",
                    help="where DIR already holds a run's fronts (its engines.json), measure and "
                         "score them again instead of searching")
    ap.add_argument("--operon-from", metavar="DIR",
                    help="take Operon's fronts from an earlier --out DIR of the same tables, "
                         "seeds and budget, and run only lgp (to compare lgp configurations "
                         "against one set of Operon runs)")
    ap.add_argument("--snapshots", type=float, default=0, metavar="S",
                    help="lgp writes its front every S seconds (lgp run --front-every); each "
                         "snapshot is measured and scored, and the report gives per k the time "
                         "lgp took to reach Operon's held-out RMS")
    ap.add_argument("--jobs", type=int, default=1,
                    help="runs at once, one core each (needs --operon-from: with Operon every "
                         "run already takes two cores)")
    args = ap.parse_args(argv)
    if args.jobs < 1:
        ap.error("--jobs must be >= 1")
    if args.jobs > 1 and not args.operon_from:
        ap.error("--jobs > 1 needs --operon-from (lgp and Operon already take two cores)")
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
    if args.snapshots < 0 or args.snapshots != args.snapshots:
        ap.error("--snapshots must be a number of seconds >= 0")
    if args.quick:
        args.budget = 10.0
    if args.budget <= 0:
        ap.error("--budget must be positive")
    if args.budget == int(args.budget):
        args.budget = int(args.budget)
    try:
        args.seed_list = [int(s) for s in args.seeds.split(",") if s]
    except ValueError:
        ap.error("--seeds: comma-separated integers")
    runs = []
    for name in [t for t in args.tables.split(",") if t] or (
            [] if args.table else ["dfg_f0_1", "dfg_f0_0p04"]):
        r = named_runs(name)
        if r is None:
            ap.error("unknown table %r" % name)
        runs += r
    if args.table:
        if not args.inputs or not args.output:
            ap.error("--table needs --inputs and --output")
        path = os.path.abspath(args.table)
        stem = args.name or os.path.splitext(os.path.basename(path))[0]
        outs = [o for o in args.output.split(",") if o]
        is_scene = path.endswith(".json")
        if not is_scene and not args.holdout:
            ap.error("a CSV --table needs --holdout CSV (a scene's held-out grid is generated)")
        for o in outs:
            r = {"name": stem if len(outs) == 1 else "%s_%s" % (stem, o),
                 "title": "%s: %s" % (stem, o), "inputs": args.inputs.split(","),
                 "weights": {o: 1.0}}
            if is_scene:
                r["scene"] = path
            else:
                r.update(csv=path, holdout=os.path.abspath(args.holdout))
            runs.append(r)
    names = [r["name"] for r in runs]
    if len(set(names)) != len(names):
        ap.error("a table is named twice")
    args.runs = runs
    return args, ap


def saved_operon_run(results_path, table, seed):
    """The run of (table, seed) in an earlier output's results.json."""
    try:
        with open(results_path) as f:
            runs = json.load(f)["runs"]
    except (OSError, ValueError, KeyError) as e:
        sys.exit("error: --operon-from: %s" % e)
    found = [r for r in runs if r.get("table") == table and r.get("seed") == seed]
    if not found:
        sys.exit("error: --operon-from: %s has no run of %s, seed %d" % (results_path, table, seed))
    r = found[0]
    # the usage row of run_together: (exit code, wall s, CPU s, killed)
    r["usage"] = [None, [0, r["operon"]["wall_s"], r["operon"]["cpu_s"], r["operon"]["killed"]]]
    return r


# Fields of prepare_data's description that fix the rows an engine trains and is scored on.
SAME_ROWS_FIELDS = ("inputs", "weights", "train_grid", "heldout_grid", "train_rows", "heldout_rows",
                    "heldout_in_train", "var_train", "var_heldout", "train_sha256",
                    "heldout_sha256")


def check_operon_from(args, ap):
    """The earlier output must hold the same tables and seeds at the same budget."""
    try:
        with open(os.path.join(args.operon_from, "results.json")) as f:
            saved = json.load(f)
        meta = saved["meta"]
    except (OSError, ValueError, KeyError) as e:
        ap.error("--operon-from: %s" % e)
    args.operon_from_tables = saved.get("tables", {})
    if meta.get("budget") != args.budget:
        ap.error("--operon-from: its budget is %s s, this run's %s s" % (meta.get("budget"),
                                                                        args.budget))
    missing = [s for s in args.seed_list if s not in meta.get("seeds", [])]
    if missing:
        ap.error("--operon-from: seeds %s are not in it" % missing)


def main():
    args, ap = parse_args()
    if args.operon_from:
        args.operon_from = os.path.abspath(args.operon_from)
        check_operon_from(args, ap)
    if not args.operon_from and (not args.operon or not os.access(args.operon, os.X_OK)):
        ap.error("operon_nsgp not found: give --operon PATH or set OPERON_NSGP")
    if not os.access(args.lgp, os.X_OK):
        ap.error("%s not found: build the lgp target, or give --lgp PATH" % args.lgp)
    args.lgp = os.path.abspath(args.lgp)
    # with --operon-from Operon does not run; its commands come from the earlier output
    args.operon = os.path.abspath(args.operon) if args.operon else "$OPERON_NSGP"
    out = os.path.abspath(args.out)
    os.makedirs(out, exist_ok=True)
    meta = {"cpu": cpu_model(), "loadavg": " ".join("%.2f" % v for v in os.getloadavg()),
            "budget": args.budget, "seeds": args.seed_list,
            "started": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            "lgp_config_json": args.config_patch, "ks": list(KS), "family": FAMILY,
            "snapshots": args.snapshots,
            "check_tolerance": {"rel": CHECK_REL, "float32_ulps_of_max_abs_y": CHECK_ULPS},
            "command": shlex.join([sys.executable] + sys.argv)}
    print("CPU: %s; load average %s" % (meta["cpu"], meta["loadavg"]), flush=True)
    if args.operon_from:
        meta["operon_from"] = args.operon_from
        meta["jobs"] = args.jobs
    data_info, tasks = {}, []
    shorten = shortener(out, args.lgp, args.operon, args.operon_from)
    for run in args.runs:
        d = os.path.join(out, run["name"])
        os.makedirs(d, exist_ok=True)
        data_info[run["name"]] = prepare_data(args.lgp, run, d)
        if args.operon_from:
            same_rows(os.path.join(args.operon_from, run["name"]), d, data_info[run["name"]],
                      args.operon_from_tables.get(run["name"]))
        tasks += [(run, seed, d) for seed in args.seed_list]
    done, lock = {}, threading.Lock()

    def one(i):
        run, seed, d = tasks[i]
        r = run_one(args, run, seed, d, data_info[run["name"]])
        with lock:  # the outputs hold the finished runs in the order of the protocol
            done[i] = r
            write_outputs(out, meta, data_info, [done[j] for j in sorted(done)], shorten)

    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        for f in [pool.submit(one, i) for i in range(len(tasks))]:
            f.result()
    print(write_outputs(out, meta, data_info, [done[j] for j in sorted(done)], shorten))


def same_rows(earlier, d, info, saved_info):
    """Operon's figures are comparable only on the same training and held-out rows: the files
    when the earlier output still has them, else the description its results.json keeps."""
    if not os.path.exists(os.path.join(earlier, "train.csv")):
        if saved_info is None:
            sys.exit("error: --operon-from: %s has neither its rows nor their description" %
                     earlier)
        for k in SAME_ROWS_FIELDS:
            if k in saved_info and saved_info[k] != info.get(k):
                sys.exit("error: --operon-from: the rows differ from this run's (%s: %r, here "
                         "%r)" % (k, saved_info[k], info.get(k)))
        return
    for name in ("train.csv", "heldout.csv"):
        try:
            with open(os.path.join(earlier, name), "rb") as a, \
                    open(os.path.join(d, name), "rb") as b:
                if a.read() != b.read():
                    sys.exit("error: --operon-from: %s differs from this run's" %
                             os.path.join(earlier, name))
        except OSError as e:
            sys.exit("error: --operon-from: %s" % e)


def shortener(out, lgp, operon, operon_from=None):
    """Machine paths out of the report: $OUT, $OPERON_NSGP, $OPERON_FROM, $LGP (outside the
    repository), paths relative to the repository, python3."""
    pairs = [(out, "$OUT")] + ([(operon, "$OPERON_NSGP")] if operon != "$OPERON_NSGP" else [])
    if operon_from:
        pairs.append((operon_from, "$OPERON_FROM"))
    if not lgp.startswith(REPO + os.sep):
        pairs.append((lgp, "$LGP"))
    pairs += [(REPO + os.sep, ""), (sys.executable, "python3")]

    def shorten(text):
        for a, b in pairs:
            text = text.replace(a, b)
        return text
    return shorten


def write_outputs(out, meta, data_info, results, shorten):
    """report.md and results.json, rewritten after every run (a long protocol leaves its
    finished runs behind if it is stopped)."""
    text = shorten(report(meta, data_info, results))
    with open(os.path.join(out, "report.md"), "w") as f:
        f.write(text)
    doc = {"meta": meta, "tables": data_info, "runs": []}
    for x in results:
        r = dict(x)
        for e in ("lgp", "operon"):
            r[e] = dict(x[e])
            r[e]["front"] = [
                {"isa": m.get("isa"), "heldout_rms": m.get("heldout_rms"),
                 "heldout_max": m.get("heldout_max"),
                 "train_rms": m.get("train_rms_f32") if e == "lgp" else m.get("train_rms_operon"),
                 "formula": m.get("formula")} for m in x[e]["members"]]
        doc["runs"].append(r)
    with open(os.path.join(out, "results.json"), "w") as f:
        f.write(shorten(json.dumps(doc, indent=1)) + "\n")
    return text


if __name__ == "__main__":
    main()
