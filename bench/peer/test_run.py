#!/usr/bin/env python3
"""The parts of bench/peer/run.py that need no Operon and no search (CTest: peer_bench_test).

    LGP=build/release/frontends/lgp python3 bench/peer/test_run.py

- Operon's infix models (fixed strings in the formatter's style) translated into lgp's formula
  grammar and scored by `lgp score --each` against values computed here by hand-written
  functions: the double-precision RMS must be ~0.
- The held-out grid: midpoints of the training grid, against closed forms of the cell centres;
  a small DFG scene through `lgp data` and prepare_data (no held-out row is a training row).
- `lgp score --each`: one result per formula, a bad formula does not stop the others, and the
  measured cost of a formula equals that of `lgp score` on it alone.
- The per-k table, the translation check and Operon's front CSV on fixed inputs.
"""
import importlib.util
import json
import math
import os
import subprocess
import sys
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.dont_write_bytecode = True  # no __pycache__ in the source tree
spec = importlib.util.spec_from_file_location("peer_run", os.path.join(HERE, "run.py"))
run = importlib.util.module_from_spec(spec)
spec.loader.exec_module(run)
spec = importlib.util.spec_from_file_location("board_operon", os.path.join(HERE, "board_operon.py"))
board_operon = importlib.util.module_from_spec(spec)
spec.loader.exec_module(board_operon)
spec = importlib.util.spec_from_file_location("compare", os.path.join(HERE, "compare.py"))
compare = importlib.util.module_from_spec(spec)
spec.loader.exec_module(compare)
LGP = os.environ.get("LGP", os.path.join(run.REPO, "build", "release", "frontends", "lgp"))

# Operon-style models and the same functions written by hand (double precision).
MODELS = [
    ("((-0.000001080394667951622978) + (1.000006079673767089843750 * ((0.5 * mu) ^ 2)))",
     lambda mu, r: -0.000001080394667951622978 + 1.000006079673767089843750 * (0.5 * mu) ** 2),
    ("(0.25 + (min((0.239770129323005676269531 * r), (0.142617836594581604003906 * mu)) - "
     "max(((-0.981357216835021972656250) * mu), ((-0.302474141120910644531250) * r))))",
     lambda mu, r: 0.25 + min(0.239770129323005676269531 * r, 0.142617836594581604003906 * mu)
     - max(-0.981357216835021972656250 * mu, -0.302474141120910644531250 * r)),
    ("((1.617863535881042480468750 + ((-0.870148479938507080078125) * r)) ^ "
     "exp((1.583908796310424804687500 * r)))",
     lambda mu, r: (1.617863535881042480468750 - 0.870148479938507080078125 * r)
     ** math.exp(1.583908796310424804687500 * r)),
    ("(log((2.5 * mu)) + (sqrt(abs(((-3.0) * r))) * (1 / (1.5 * mu))))",
     lambda mu, r: math.log(2.5 * mu) + math.sqrt(abs(-3.0 * r)) / (1.5 * mu)),
    ("((-(0.5 * mu)) - (0.125 * r) - 0.0625)",
     lambda mu, r: -0.5 * mu - 0.125 * r - 0.0625),
    ("(exp(((-7.434512615203857421875000) * mu)) / (1.161509752273559570312500 + "
     "(4.812085151672363281250000 * r)))",
     lambda mu, r: math.exp(-7.434512615203857421875000 * mu)
     / (1.161509752273559570312500 + 4.812085151672363281250000 * r)),
]
# Dyadic inputs: exact in float32, so lgp's float32 inputs are the ones used here.
GRID = [(0.125 + 0.125 * i, 0.0625 * j) for i in range(8) for j in range(16)]


def lgp_available():
    return os.access(LGP, os.X_OK)


def sh(cmd):
    return subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


class Translation(unittest.TestCase):
    def test_text(self):
        self.assertEqual(run.translate("((0.5 * mu) ^ 2)", ["mu"]), "y = square((0.5 * mu))")
        self.assertEqual(run.translate("((0.5 * mu) ^ 2.5)", ["mu"]), "y = pow((0.5 * mu), 2.5)")
        self.assertEqual(run.translate("fmax((-mu), (1 / mu))", ["mu"]),
                         "y = max((-mu), (1 / mu))")
        for bad in ("(tanh(mu))", "(mu + z)", "(mu +", "min(mu)"):
            with self.assertRaises(ValueError, msg=bad):
                run.translate(bad, ["mu"])

    def test_python_evaluator_matches_hand_written(self):
        for text, f in MODELS:
            g = run.operon_function(text, ["mu", "r"])
            for mu, r in GRID:
                self.assertAlmostEqual(g([mu, r]), f(mu, r), delta=1e-12 * (1 + abs(f(mu, r))),
                                       msg=text)

    @unittest.skipUnless(lgp_available(), "no lgp CLI at $LGP")
    def test_lgp_scores_translations_as_the_hand_written_functions(self):
        with tempfile.TemporaryDirectory() as d:
            for i, (text, f) in enumerate(MODELS):
                path = os.path.join(d, "t%d.csv" % i)
                rows = [([repr(mu), repr(r)], f(mu, r)) for mu, r in GRID]
                run.write_rows(path, ["mu", "r"], rows)
                res = run.lgp_score_each(LGP, path, ["mu", "r"],
                                         [run.translate(text, ["mu", "r"])],
                                         os.path.join(d, "f.txt"), False, [])
                self.assertEqual(len(res), 1)
                self.assertNotIn("failed", res[0], text)
                scale = max(abs(y) for _, y in rows)
                self.assertLess(run.metric(res[0], "double", "rmse"), 1e-9 * scale, text)
                self.assertLess(run.metric(res[0], "float32", "max_abs"), 2e-5 * scale, text)
                # A constant off by one part in 10^4 is seen.
                wrong = text.replace("0.5", "0.50005", 1).replace("2.5", "2.50025", 1)
                if wrong != text:
                    res = run.lgp_score_each(LGP, path, ["mu", "r"],
                                             [run.translate(wrong, ["mu", "r"])],
                                             os.path.join(d, "f.txt"), False, [])
                    self.assertGreater(run.metric(res[0], "double", "rmse"), 1e-6 * scale, text)


class HeldOut(unittest.TestCase):
    def test_dfg_midpoints_are_the_cell_centres(self):
        with open(run.DFG_SCENE) as f:
            scene = json.load(f)
        n = 64
        grid = {"mu": {"values": [1 / 64 + (1 - 1 / 64) * i / (n - 1) for i in range(n)]},
                "r": {"values": [i / (n - 1) for i in range(n)]}}
        h = run.heldout_scene(scene, grid, ["mu", "r"], True)
        mu = [1 / 64 + (1 - 1 / 64) * (i + 0.5) / (n - 1) for i in range(n - 1)]
        r = [(i + 0.5) / (n - 1) for i in range(n - 1)]
        self.assertEqual(list(h["grid"]), ["mu", "r"])  # row order kept
        for got, want in ((h["grid"]["mu"]["values"], mu), (h["grid"]["r"]["values"], r)):
            self.assertEqual(len(got), n - 1)
            for a, b in zip(got, want):
                self.assertAlmostEqual(a, b, delta=1e-15)
        self.assertEqual({k: v for k, v in h.items() if k not in ("grid", "name", "description")},
                         {k: v for k, v in scene.items()
                          if k not in ("grid", "name", "description")})

    def test_cell_axis_and_an_axis_that_is_no_input(self):
        scene = {"grid": {"mu": {"count": 4, "spacing": "cell"}, "r": {"count": 3}}}
        grid = {"mu": {"values": [0.125, 0.375, 0.625, 0.875]}, "r": {"values": [0, 0.5, 1]}}
        h = run.heldout_scene(scene, grid, ["r"], True)
        self.assertEqual(h["grid"]["mu"], {"values": [0.125]})
        self.assertEqual(h["grid"]["r"], {"values": [0.25, 0.75]})
        h = run.heldout_scene(scene, grid, ["r"], False)  # not a function of r: mu varies too
        self.assertEqual(h["grid"]["mu"], {"values": [0.25, 0.5, 0.75]})

    def test_dedupe(self):
        rows = [(["1"], 2.0), (["1"], 2.0), (["2"], 3.0), (["2"], 3.0)]
        self.assertEqual(run.dedupe(rows), ([(["1"], 2.0), (["2"], 3.0)], 2))
        uneven = rows + [(["2"], 3.0)]
        self.assertEqual(run.dedupe(uneven), (uneven, 1))
        self.assertTrue(run.is_function(rows))
        self.assertFalse(run.is_function(rows + [(["1"], 5.0)]))

    @unittest.skipUnless(lgp_available(), "no lgp CLI at $LGP")
    def test_small_scene_through_lgp_data(self):
        with open(run.DFG_SCENE) as f:
            scene = json.load(f)
        scene["grid"] = {"mu": {"count": 5, "range": [0.2, 1.0], "spacing": "edge"},
                         "r": {"count": 4, "range": [0.25, 1.0], "spacing": "cell"}}
        scene["accuracy"] = {"abs_error": 1e-4}
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "scene.json")
            with open(path, "w") as f:
                json.dump(scene, f)
            r = run.dfg_channel("t", "t", 0.04)
            r["scene"] = path
            info = run.prepare_data(LGP, r, d)
            self.assertEqual((info["train_rows"], info["heldout_rows"]), (20, 12))
            self.assertEqual(info["heldout_in_train"], 0)
            held = run.load_rows(os.path.join(d, "heldout.csv"), ["mu", "r"])
            mus = sorted({x[0] for x, _ in held})
            rs = sorted({x[1] for x, _ in held})
            want_mu = [0.2 + 0.8 * (i + 0.5) / 4 for i in range(4)]  # cell centres of the edges
            want_r = [0.25 + 0.75 * (i + 1) / 4 for i in range(3)]  # between the cell centres
            for got, want in ((mus, want_mu), (rs, want_r)):
                self.assertEqual(len(got), len(want))
                for a, b in zip(got, want):
                    self.assertAlmostEqual(a, b, delta=1e-12)
            # y = 0.04 A + B from the generated held-out table.
            full = run.read_csv(os.path.join(d, "heldout-table.csv"))
            for (x, y), row in zip(held, full):
                self.assertAlmostEqual(y, 0.04 * float(row["A"]) + float(row["B"]), delta=1e-15)
            with open(os.path.join(d, "operon-data.csv")) as f:
                self.assertEqual(len(f.read().splitlines()), 1 + 20 + 12)


class ScoreEach(unittest.TestCase):
    @unittest.skipUnless(lgp_available(), "no lgp CLI at $LGP")
    def test_each_formula_alone_and_measured_as_alone(self):
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "t.csv")
            run.write_rows(path, ["mu", "r"], [([repr(mu), repr(r)], mu * r + 0.5)
                                               for mu, r in GRID])
            formulas = ["y = mu*r + 0.5", "y = nosuchname + 1", "y = exp2(-(7*mu + 4*r*r))"]
            res = run.lgp_score_each(LGP, path, ["mu", "r"], formulas, os.path.join(d, "f.txt"),
                                     True, [])
            self.assertEqual([x["index"] for x in res], [0, 1, 2])
            self.assertLess(run.metric(res[0], "double", "rmse"), 1e-12)
            self.assertIn("failed", res[1])
            self.assertGreater(run.metric(res[2], "double", "rmse"), 0.01)
            alone = json.loads(sh([LGP, "score", path, "--inputs", "mu,r", "--outputs", "y",
                                   "--expr", formulas[2], "--json"]).stdout)
            self.assertEqual(res[2]["outputs"], alone["outputs"])
            self.assertEqual(res[2].get("cost_measured"), alone.get("cost_measured"))
            if "cost_measured" in alone:  # the ISA backend is here
                self.assertGreater(run.isa_of(res[2]["cost_measured"]), 3)
                self.assertGreater(run.isa_of(res[2]["cost_measured"]),
                                   run.isa_of(res[0]["cost_measured"]))
            # Text mode: a header and one line per formula.
            p = sh([LGP, "score", path, "--inputs", "mu,r", "--outputs", "y", "--each",
                    "--expr-file", os.path.join(d, "f.txt"), "--no-measure"])
            self.assertEqual(p.returncode, 0, p.stderr)
            self.assertEqual(len(p.stdout.splitlines()), 4)
            self.assertIn("failed", p.stdout.splitlines()[2])


class Tables(unittest.TestCase):
    def test_per_k(self):
        m = [{"isa": 5, "heldout_rms": 0.1, "heldout_max": 0.3, "check": True},
             {"isa": 12, "heldout_rms": 0.01, "heldout_max": 0.5, "check": True},
             {"isa": 30, "heldout_rms": 0.001, "heldout_max": 0.01, "check": False},
             {"isa": 9, "heldout_rms": None, "heldout_max": None, "check": True}]
        t = run.per_k(m)
        self.assertEqual(t["8"], {"rms": 0.1, "max": 0.3, "rms_unchecked": False,
                                  "max_unchecked": False})
        self.assertEqual(t["10"], t["8"])  # the member without held-out figures is left out
        # Each figure minimised on its own.
        self.assertEqual((t["12"]["rms"], t["12"]["max"]), (0.01, 0.3))
        # A member that failed the translation check counts, and is marked.
        self.assertEqual(t["64"], {"rms": 0.001, "max": 0.01, "rms_unchecked": True,
                                   "max_unchecked": True})
        self.assertEqual(run.per_k(m[1:])["8"]["rms"], None)
        self.assertEqual(run.ratio(0.5, 0.25), 2.0)
        self.assertIsNone(run.ratio(None, 0.25))

    def test_time_to_operon(self):
        # Operon's final figures at k = 8 and 64 (none at or below 10 ... 50 for this test).
        ks = [str(k) for k in run.KS]
        op = {k: {"rms": None} for k in ks}
        op["8"]["rms"], op["64"]["rms"] = 0.02, 0.001
        snaps = [{"search_s": 30.2, "rms": {"8": 0.03, "64": 0.004}},
                 {"search_s": 60.1, "rms": {"8": 0.02, "64": 0.002}}]
        final = {k: {"rms": None} for k in ks}
        final["8"]["rms"], final["64"]["rms"] = 0.01, 0.0015
        t = run.time_to_operon(snaps, final, 300.0, op)
        self.assertEqual(t["8"], 60.1)  # reached exactly at the second snapshot
        self.assertIsNone(t["64"])  # never: 0.0015 > 0.001 at the end
        self.assertIsNone(t["10"])  # Operon has no member there
        final["64"]["rms"] = 0.0009
        self.assertEqual(run.time_to_operon(snaps, final, 300.0, op)["64"], 300.0)
        self.assertIsNone(run.time_to_operon([], final, 300.0, op))
        args, _ = run.parse_args(["--out", "x", "--snapshots", "30"])
        self.assertEqual(args.snapshots, 30)
        with self.assertRaises(SystemExit):
            run.parse_args(["--out", "x", "--snapshots", "-1"])

    def test_check(self):
        self.assertTrue(run.check_ok(1.0005e-3, 1e-3, 1.0))
        self.assertFalse(run.check_ok(1.002e-3, 1e-3, 1.0))
        self.assertTrue(run.check_ok(1.002e-3, 1e-3, 100.0))  # within an ulp of 100
        self.assertFalse(run.check_ok(math.nan, 1e-3, 1.0))

    def test_operon_front(self):
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "front.csv")
            with open(path, "w") as f:
                f.write("length,complexity_obj,r2_train,r2_test,nmse_train,nmse_test,mae_train,"
                        "mae_test,model\n")
                f.write('3,3,0.99,0.98,0.01,0.04,0.1,0.1,"(1.5 * mu)"\n')
                f.write('1,1,nan,nan,nan,nan,nan,nan,"0.5"\n')
            members, dropped = run.read_operon_front(path, 4.0, 9.0)
        self.assertEqual(dropped, 1)
        self.assertEqual(len(members), 1)
        self.assertAlmostEqual(members[0]["train_rms_operon"], math.sqrt(0.01 * 4.0))
        self.assertAlmostEqual(members[0]["heldout_rms_operon"], math.sqrt(0.04 * 9.0))

    def test_named_tables(self):
        self.assertEqual([r["name"] for r in run.named_runs("dfg")], ["dfg_f0_1", "dfg_f0_0p04"])
        zh = run.named_runs("zh")
        self.assertEqual([r["weights"] for r in zh],
                         [{"ZH0": 1.0}, {"ZH1_over_ZH0": 1.0}, {"ZH2_over_ZH0": 1.0}])
        for name in ("normalization", "energy"):
            (r,) = run.named_runs(name)
            self.assertTrue(os.path.exists(r["scene"]), r["scene"])
        self.assertIsNone(run.named_runs("nosuchtable"))
        args, _ = run.parse_args(["--out", "x", "--tables", "dfg_f0_0p04,energy", "--quick",
                                  "--seeds", "1,2"])
        self.assertEqual((args.budget, args.seed_list), (10, [1, 2]))
        self.assertEqual([r["name"] for r in args.runs], ["dfg_f0_0p04", "energy"])
        cfg = run.lgp_config(["mu", "r"], 10, 2, {"search": {"seed": 9, "population": 50}})
        self.assertEqual(cfg["search"]["seed"], 2)  # the protocol wins
        self.assertEqual(cfg["search"]["population"], 50)
        self.assertTrue(cfg["search"]["linear_scaling"])


class BoardOperon(unittest.TestCase):
    """The scoreboard's Operon column: best RMS and best max at ISA <= k, over seeds."""

    def test_cumulative_best_over_seeds_without_failed_translations(self):
        def member(isa, rms, mx, check=True):
            return {"isa": isa, "heldout_rms": rms, "heldout_max": mx, "check": check}
        res = {"runs": [
            {"table": "dfg_f0_1", "operon": {"members": [member(3, 0.1, 0.5), member(9, 0.02, 0.3),
                                                          member(5, 0.001, 0.01, check=False)]}},
            {"table": "dfg_f0_1", "operon": {"members": [member(5, 0.05, 0.6)]}},
            {"table": "sheen", "operon": {"members": [member(4, 0.2, float("nan"))]}}]}
        got = board_operon.entries([res])["tables"]
        self.assertEqual(list(got), ["dfg"])  # the NaN member is left out, and its table
        self.assertEqual([(e["channel"], e["isa_max"], e["rmse"], e["max_abs"]) for e in got["dfg"]],
                         [("F0=1", 3, 0.1, 0.5), ("F0=1", 5, 0.05, 0.5), ("F0=1", 9, 0.02, 0.3)])

    def test_per_output_runs_are_not_board_channels(self):
        def member(isa, rms):
            return {"isa": isa, "heldout_rms": rms, "heldout_max": 2 * rms, "check": True}
        res = {"runs": [{"table": "zh_ZH0", "operon": {"members": [member(4, 0.02)]}},
                        {"table": "normalization", "operon": {"members": [member(6, 0.03)]}}]}
        got = board_operon.entries([res])["tables"]
        self.assertEqual(sorted(got), ["normalization", "zh_ZH0"])  # the board has no zh_ZH0
        self.assertEqual([(e.get("channel"), e["isa_max"]) for e in got["normalization"]],
                         [(None, 6)])


class CompareArms(unittest.TestCase):
    """The ablation table: per-k geometric mean of arm / base over the runs both have."""

    def test_geometric_mean_and_operon_count(self):
        def run(table, seed, lgp, operon):
            return {"table": table, "seed": seed,
                    "per_k": {"8": {"lgp_rms": lgp, "operon_rms": operon},
                              "10": {"lgp_rms": None, "operon_rms": operon}}}
        base = {("a", 1): run("a", 1, 0.4, 0.2), ("b", 1): run("b", 1, 0.1, 0.3)}
        arm = {("a", 1): run("a", 1, 0.1, 0.2), ("b", 1): run("b", 1, 0.4, 0.3),
               ("c", 1): run("c", 1, 0.5, 0.1)}  # no base run: left out of the mean
        g, n = compare.geomean_ratio(arm, base, 8, "lgp_rms")
        self.assertEqual(n, 2)
        self.assertAlmostEqual(g, 1.0)  # sqrt(0.25 * 4)
        self.assertEqual(compare.geomean_ratio(arm, base, 10, "lgp_rms"), (None, 0))
        text = compare.report([("base", base), ("arm", arm)])
        self.assertIn("| arm | 2 | 1.00 | - |", text)
        self.assertIn("| 1 of 3 |", text)  # a at 8 is below Operon; b and c are not

    def test_median_and_worst_over_seeds(self):
        def run(seed, ratio, t):
            return {"table": "a", "seed": seed, "time_to_operon": {"8": t},
                    "per_k": {"8": {"lgp_rms": 1, "operon_rms": 1, "rms_ratio": ratio}}}
        arm = {("a", 1): run(1, 0.5, 40.0), ("a", 2): run(2, 2.0, None),
               ("a", 3): run(3, 0.8, 100.0)}
        text = "\n".join(compare.seeds_table([("x", arm)]))
        self.assertIn("| x | a | RMS ratio | 3 | 0.80 \\| 2.00 |", text)
        # seed 2 never reached Operon's figure: the worst is "-", the median 100 s
        self.assertIn("| x | a | seconds to Operon | 3 | 100 \\| - |", text)

    def test_interval_of_the_geometric_mean(self):
        # log ratios 0, ln 2, ln 4: mean ln 2, sd ln 2, t(2 df) = 2.920, half width 2.920 ln2/sqrt3
        logs = [0.0, math.log(2), math.log(4)]
        lo, hi = compare.geomean_interval(logs)
        h = 2.920 * math.log(2) / math.sqrt(3)
        self.assertAlmostEqual(lo, math.exp(math.log(2) - h))
        self.assertAlmostEqual(hi, math.exp(math.log(2) + h))
        self.assertIsNone(compare.geomean_interval(logs[:2]))  # too few runs to say

    def test_an_arm_from_several_outputs(self):
        d = tempfile.mkdtemp()

        def out(name, seeds):
            path = os.path.join(d, name)
            with open(path, "w") as f:
                json.dump({"runs": [{"table": "t", "seed": s, "per_k": {}} for s in seeds]}, f)
            return path
        a, b, c = out("a.json", [1, 2]), out("b.json", [3]), out("c.json", [2])
        arms = compare.load(["x=%s,%s" % (a, b)])
        self.assertEqual(sorted(arms[0][1]), [("t", 1), ("t", 2), ("t", 3)])
        with self.assertRaises(SystemExit):  # seed 2 twice in one arm
            compare.load(["x=%s,%s" % (a, c)])


class Jobs(unittest.TestCase):
    """--jobs runs lgp runs side by side: each must reap only its own children."""

    def test_concurrent_run_together_reaps_its_own(self):
        import threading
        out = {}

        def jobs(tag, seconds):
            d = tempfile.mkdtemp()
            return [{"argv": ["sh", "-c", "sleep %g; exit %d" % (seconds, code)], "env": {},
                     "cwd": d, "stdout": os.path.join(d, "o%d" % code),
                     "stderr": os.path.join(d, "e%d" % code)} for code in (tag, tag + 1)]

        def one(tag, seconds):
            out[tag] = run.run_together(jobs(tag, seconds), deadline_s=60)

        threads = [threading.Thread(target=one, args=(t, s)) for t, s in ((10, 0.4), (20, 0.1))]
        for t in threads:
            t.start()
        subprocess.run(["sh", "-c", "sleep 0.2"], check=True)  # a third thread's child
        for t in threads:
            t.join()
        self.assertEqual([r[0] for r in out[10]], [10, 11])
        self.assertEqual([r[0] for r in out[20]], [20, 21])
        self.assertGreater(min(r[1] for r in out[10]), 0.35)
        self.assertLess(max(r[1] for r in out[20]), 0.35)  # its own end time, not the others'

    def test_jobs_need_operon_from(self):
        with self.assertRaises(SystemExit):
            run.parse_args(["--out", "x", "--jobs", "2"])
        with self.assertRaises(SystemExit):
            run.parse_args(["--out", "x", "--jobs", "0", "--operon-from", "y"])
        args, _ = run.parse_args(["--out", "x", "--jobs", "2", "--operon-from", "y"])
        self.assertEqual(args.jobs, 2)

    def test_operon_from_needs_the_same_budget_and_seeds(self):
        d = tempfile.mkdtemp()
        with open(os.path.join(d, "results.json"), "w") as f:
            json.dump({"meta": {"budget": 300, "seeds": [1, 2]}}, f)
        for argv in (["--budget", "200"], ["--seeds", "3"]):
            args, ap = run.parse_args(["--out", "x", "--operon-from", d] + argv)
            with self.assertRaises(SystemExit):
                run.check_operon_from(args, ap)
        args, ap = run.parse_args(["--out", "x", "--operon-from", d, "--seeds", "2"])
        run.check_operon_from(args, ap)  # accepted

    def test_operon_from_a_committed_output(self):
        """Without its run folders an earlier output gives Operon's scored run from its
        results.json, after the rows' description matches this run's."""
        d = tempfile.mkdtemp()
        info = {"inputs": ["mu"], "weights": {"y": 1.0}, "train_rows": 4, "heldout_rows": 3,
                "var_train": 0.25, "var_heldout": 0.5, "train_grid": {"mu": 4}}
        member = {"isa": 3.0, "heldout_rms": 0.1, "heldout_max": 0.2, "check": True}
        operon = {"generations": 7, "evaluations": 70, "search_s": 300.0, "wall_s": 300.5,
                  "cpu_s": 299.0, "killed": False, "members": [member], "dropped_not_finite": 0}
        with open(os.path.join(d, "results.json"), "w") as f:
            json.dump({"meta": {"budget": 300, "seeds": [1]}, "tables": {"t": info},
                       "runs": [{"table": "t", "seed": 1, "commands": ["lgp", "operon --seed 1"],
                                 "operon": operon}]}, f)
        r = run.saved_operon_run(os.path.join(d, "results.json"), "t", 1)
        self.assertEqual(r["operon"]["members"], [member])
        self.assertEqual(r["usage"][1], [0, 300.5, 299.0, False])
        with self.assertRaises(SystemExit):
            run.saved_operon_run(os.path.join(d, "results.json"), "t", 2)
        args, ap = run.parse_args(["--out", "x", "--operon-from", d, "--seeds", "1"])
        run.check_operon_from(args, ap)
        self.assertEqual(args.operon_from_tables, {"t": info})
        run.same_rows(os.path.join(d, "t"), d, dict(info, train_sha256="ab"), info)  # accepted
        with self.assertRaises(SystemExit):
            run.same_rows(os.path.join(d, "t"), d, dict(info, var_train=0.26), info)
        with self.assertRaises(SystemExit):  # neither rows nor a description
            run.same_rows(os.path.join(d, "t"), d, info, None)


if __name__ == "__main__":
    unittest.main()
