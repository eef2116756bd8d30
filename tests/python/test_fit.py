"""lgp.fit, Front and Member: recovery, predictions against the engine, bad arguments."""

import json
import os
import re
import subprocess
import sys
import textwrap
import threading
import time

import numpy as np
import pytest

import lgp
from conftest import target

OPS = ["add", "sub", "mul", "mad", "neg", "square", "exp2"]


def test_fit_recovers_exp2_on_most_seeds(grid):
    X, y = grid
    recovered = []
    for seed in range(1, 6):
        front = lgp.fit(X, y, inputs=["x", "y"], outputs=["f"], ops=OPS, generations=150,
                        threads=1, seed=seed, search={"population": 200})
        best = front.best()
        recovered.append(best.metrics["f"]["rmse"] < 1e-5)
    # Measured at 10 of 10 (seeds 1 to 10) on the development machine; a search that loses
    # its way on more than two of these five has regressed.
    assert sum(recovered) >= 3, recovered


def test_front_is_the_front_json(grid):
    X, y = grid
    front = lgp.fit(X, y, inputs=["x", "y"], ops=OPS, generations=30, threads=1, seed=3)
    assert front.data["format"] == "lgp-front/1"
    # The default output name is y, or f where an input is called y.
    assert front.inputs == ["x", "y"] and front.outputs == ["f"]
    costs = [m.cost for m in front]
    assert costs == sorted(costs)
    for m in front:
        # Shared sub-expressions print first ("t0 = x - 0.8; f = t0*t0"); the output is last.
        assert np.isfinite(m.error) and m.formula.split("; ")[-1].startswith("f = ")
        assert set(m.cost_by_target) >= {"gpu-generic", "rdna", "nvidia"}
    assert front.progress["generation"] == 30
    assert front.config["search"]["seed"] == 3


def test_predict_matches_the_interpreters_scores(grid):
    # The front records each member's float32 metrics as the engine's Scorer measured them;
    # predict() must reproduce them from the same rows.
    X, y = grid
    front = lgp.fit(X, y, inputs=["x", "y"], ops=OPS, generations=40, threads=1, seed=2)
    for m in front:
        p = m.predict(X)
        assert p.shape == (len(y),) and p.dtype == np.float64
        # float32 values: exactly representable
        assert np.array_equal(p, p.astype(np.float32).astype(np.float64))
        rec = m.metrics[front.outputs[0]]
        rmse = float(np.sqrt(np.mean((p - y) ** 2)))
        assert rmse == pytest.approx(rec["rmse"], rel=1e-5, abs=1e-9)
        assert float(np.max(np.abs(p - y))) == pytest.approx(rec["max_abs"], rel=1e-5, abs=1e-9)
        # the double reference path agrees to float32 rounding
        d = m.predict(X, double_precision=True)
        assert np.allclose(p, d, rtol=1e-5, atol=1e-6)


def test_predict_is_the_emitted_exact_math_cpp(grid, tmp_path):
    # C++ float with exact_math is bit-identical to the float32 interpreter (emit/README.md)
    # when compiled with -ffp-contract=off and the engine's FMA setting: compile it, run it on
    # the rows, compare bits with predict().
    X, y = grid
    front = lgp.fit(X, y, inputs=["x", "y"], ops=OPS, generations=40, threads=1, seed=2)
    m = front.best()
    code = m.emit("cpp", exact_math=True, name="f")
    src = tmp_path / "m.cpp"
    src.write_text(code + textwrap.dedent("""
        #include <cstdio>
        int main() {
          double a, b;
          while (std::scanf("%lf %lf", &a, &b) == 2)
            std::printf("%.9g\\n", (double)f((float)a, (float)b));
        }
    """))
    exe = tmp_path / "m"
    # FMA on exactly where the engine's build had it (LGP_ARCH_FLAGS: its -march).
    arch = os.environ.get("LGP_ARCH_FLAGS", "").split()
    subprocess.run(["c++", "-std=c++17", "-O2", "-ffp-contract=off", *arch, str(src), "-o",
                    str(exe)], check=True)
    rows = "\n".join(f"{a!r} {b!r}" for a, b in X)
    out = subprocess.run([str(exe)], input=rows, capture_output=True, text=True, check=True)
    got = np.array([float(v) for v in out.stdout.split()])
    assert np.array_equal(got.astype(np.float32), m.predict(X).astype(np.float32))


def test_table_and_config_sources(tmp_path, examples):
    # A table file, a config file, and keyword sections merged into it.
    front = lgp.fit(table=os.path.join(examples, "quickstart.csv"), inputs=["mu", "r"],
                    outputs=["B"], generations=20, threads=1)
    assert front.outputs == ["B"]
    front2 = lgp.fit(config=os.path.join(examples, "quickstart.json"), generations=20,
                     threads=1, program={"max_length": 8})
    assert front2.config["program"]["max_length"] == 8
    assert front2.config["data"]["path"].endswith("quickstart.csv")


def test_multi_output_and_table_object(grid):
    X, y = grid
    Y = np.stack([y, 1 - X[:, 0]], axis=1)
    t = lgp.Table(X, Y, ["x", "y"], ["A", "B"])
    front = lgp.fit(t, ops=OPS, generations=20, threads=1)
    assert front.outputs == ["A", "B"]
    p = front.best().predict(X)
    assert p.shape == (len(X), 2)


@pytest.mark.parametrize("kwargs, field", [
    (dict(generations=-1), "generations"),
    (dict(seconds="1"), "seconds"),
    (dict(threads=1.5), "threads"),
    (dict(ops=["add", "nope"]), "/program/ops"),
    (dict(search={"population": 2}), "/search/population"),
    (dict(objectives={"error": "l7"}), "/objectives/error"),
    (dict(popsize=10), "popsize"),
    (dict(program=3), "program"),
    (dict(progress="yes"), "progress"),
    (dict(inputs=["a"]), "inputs"),
    # JSON has no infinity: named here, not "invalid JSON literal" from the engine.
    (dict(seconds=float("inf")), "seconds: must be a finite number"),
    (dict(search={"wall_time_s": float("nan")}), "/search/wall_time_s: must be a finite number"),
])
def test_bad_arguments_name_the_field(grid, kwargs, field):
    X, y = grid
    args = dict(generations=5, threads=1)
    args.update(kwargs)
    with pytest.raises(ValueError, match=field.replace("/", "\\/")):
        lgp.fit(X, y, **args)


def test_bad_data_names_the_field(grid):
    X, y = grid
    with pytest.raises(ValueError, match="y: has 3 rows"):
        lgp.fit(X, y[:3], generations=5)
    bad = X.copy()
    bad[4, 1] = np.nan
    with pytest.raises(ValueError, match="column 'x1', row 5"):  # rows counted from 1
        lgp.fit(bad, y, generations=5)
    with pytest.raises(ValueError, match="data"):
        lgp.fit(generations=5)
    with pytest.raises(ValueError, match="t.csv: cannot open"):  # as `lgp run` says it
        lgp.fit(table="/nonexistent/t.csv", generations=5)
    front = lgp.fit(X, y, generations=5, threads=1)
    with pytest.raises(ValueError, match="X: has 3 columns"):
        front.best().predict(np.zeros((4, 3)))
    with pytest.raises(IndexError, match="member"):
        front[len(front)]
    with pytest.raises(ValueError, match="max_cost"):
        front.best(max_cost=-1)


def _edited(front, edit):
    """A copy of a front's JSON changed by `edit`, as a Front (a file anyone can write)."""
    data = json.loads(json.dumps(front.data))
    edit(data)
    return lgp.Front(data)


def test_predict_holds_a_front_to_the_configs_bounds(grid):
    # eval.block_size comes from the front: 2^24 cost 800 MiB to predict one row; it gets the
    # bounds a run config has, naming the field.
    X, y = grid
    front = lgp.fit(X, y, generations=3, threads=1)
    for size, why in ((1 << 24, "must be in [16, 16384]"), (24, "must be a multiple of 16"),
                      ("256", "must be an integer")):
        bad = _edited(front, lambda d: d["config"]["eval"].update(block_size=size))
        with pytest.raises(ValueError, match=re.escape(f"front: /config/eval/block_size: {why}")):
            bad[0].predict(X[:1])
    ok = _edited(front, lambda d: d["config"]["eval"].update(block_size=16))
    assert np.array_equal(ok[0].predict(X), front[0].predict(X))


@pytest.mark.parametrize("edit, field", [
    (lambda d: d.pop("config"), "front: /config: missing"),
    (lambda d: d["config"].pop("eval"), "front: /config/eval: missing"),
    (lambda d: d["members"][0].pop("outputs"), "front: /members/0/outputs: missing"),
    (lambda d: d["members"][0].pop("program"), "front: /members/0/program: missing"),
    (lambda d: d["members"][0]["outputs"][0].update(transform="cube"),
     "front: /members/0/outputs/0/transform: not a target transform"),
    (lambda d: d["table"].pop("outputs"), "front: /table/outputs: missing"),
    (lambda d: d.pop("table"), "front: /table/inputs: missing"),
])
def test_predict_names_a_missing_field(grid, edit, field):
    # Read through unchecked access before (undefined behaviour; a raw RuntimeError).
    X, y = grid
    bad = _edited(lgp.fit(X, y, generations=3, threads=1), edit)
    with pytest.raises(ValueError, match=re.escape(field)):
        bad[0].predict(X[:2])


def test_same_seed_same_front(grid):
    X, y = grid
    a = lgp.fit(X, y, ops=OPS, generations=25, threads=2, seed=9)
    b = lgp.fit(X, y, ops=OPS, generations=25, threads=2, seed=9)
    assert [m.program for m in a] == [m.program for m in b]


def test_progress_callback_and_gil_released(grid):
    # The search runs without the GIL: a Python thread keeps running meanwhile. Held for the
    # whole search, the thread would stall for all of its 3 seconds.
    X, y = grid
    seen = []
    stamps = []
    stop = threading.Event()

    def count():
        while not stop.is_set():
            stamps.append(time.monotonic())
            time.sleep(0.005)

    t = threading.Thread(target=count)
    t.start()
    try:
        t0 = time.monotonic()
        lgp.fit(X, y, ops=OPS, seconds=3, threads=1, progress=seen.append,
                progress_interval=0.2)
        t1 = time.monotonic()
    finally:
        stop.set()
        t.join()
    assert len(seen) >= 3 and all("generation" in p for p in seen)
    assert seen[-1]["generation"] >= seen[0]["generation"]
    during = [s for s in stamps if t0 <= s <= t1]
    gaps = np.diff([t0] + during + [t1])
    assert len(during) > 20 and gaps.max() < 1.5, (len(during), gaps.max())


def test_ctrl_c_returns_the_front(tmp_path):
    # SIGINT in a subprocess: the fit stops after its generation and returns a front.
    script = tmp_path / "run.py"
    script.write_text(textwrap.dedent("""
        import json, sys, warnings
        import numpy as np
        import lgp
        g = np.linspace(0, 1, 16)
        X = np.array([(a, b) for b in g for a in g])
        y = np.exp2(-7 * X[:, 0] - 4 * X[:, 1] ** 2)
        started = []
        def progress(p):
            if not started:
                started.append(1)
                print("started", flush=True)
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always")
            front = lgp.fit(X, y, seconds=120, threads=1, progress=progress,
                            progress_interval=0.1)
        print(json.dumps({"members": len(front), "interrupted": front.interrupted,
                          "stop": front.progress["stop_reason"],
                          "warned": any("interrupted" in str(x.message) for x in w)}))
    """))
    p = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True,
                         env=os.environ.copy())
    assert p.stdout.readline().strip() == "started"
    time.sleep(0.5)
    t0 = time.monotonic()
    p.send_signal(2)
    out, _ = p.communicate(timeout=60)
    elapsed = time.monotonic() - t0
    assert p.returncode == 0
    doc = json.loads(out.strip().splitlines()[-1])
    assert doc["members"] > 0 and doc["interrupted"] and doc["warned"]
    assert doc["stop"] == "stopped"
    assert elapsed < 30  # not the 120 s budget


@pytest.mark.parametrize("call", ["data", "fit"])
def test_ctrl_c_stops_a_scene_being_generated(tmp_path, call):
    # Hardening round 4, F2: a scene's table was generated without the GIL and without a
    # stop, so Ctrl-C waited for every row (minutes for a large scene). Now KeyboardInterrupt
    # comes within a fraction of a second of the signal.
    scene = {"material": {"fresnel": {"model": "dielectric"}}, "outputs": ["E_dielectric"],
             "grid": {"mu": {"count": 40}, "r": {"count": 40}, "eta": {"count": 40,
                                                                     "range": [1.1, 2.5]}}}
    script = tmp_path / "gen.py"
    script.write_text(textwrap.dedent(f"""
        import json, sys, time
        import lgp
        scene = {scene!r}
        print("started", flush=True)
        t0 = time.monotonic()
        try:
            if {call!r} == "data":
                lgp.data(scene, cache_dir="-", threads=1)
            else:
                with open(sys.argv[1], "w") as f:
                    json.dump(scene, f)
                lgp.fit(scene=sys.argv[1], data={{"cache_dir": "-"}}, generations=1, threads=1)
            print("finished")
        except KeyboardInterrupt:
            print("interrupted", time.monotonic() - t0)
    """))
    p = subprocess.Popen([sys.executable, str(script), str(tmp_path / "scene.json")],
                         stdout=subprocess.PIPE, text=True, env=os.environ.copy())
    assert p.stdout.readline().strip() == "started"
    time.sleep(1.0)
    t0 = time.monotonic()
    p.send_signal(2)
    out, _ = p.communicate(timeout=60)
    assert out.startswith("interrupted"), out
    assert time.monotonic() - t0 < 5  # 64,000 rows take minutes


def test_cache_dir_dash_means_no_cache_everywhere(tmp_path, monkeypatch):
    # Hardening round 4, F13: lgp.fit(data={"cache_dir": "-"}) created a directory named "-"
    # where lgp.data(cache_dir="-") means no cache.
    monkeypatch.chdir(tmp_path)
    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps({"outputs": ["A", "B"],
                                 "material": {"fresnel": {"model": "schlick", "f90": 1}},
                                 "grid": {"mu": {"count": 6}, "r": {"count": 6}}}))
    front = lgp.fit(scene=str(scene), data={"cache_dir": "-"}, generations=2, threads=1,
                    ops=OPS)
    assert len(front) > 0
    assert not (tmp_path / "-").exists()


def test_load_front_and_save(tmp_path, grid):
    X, y = grid
    front = lgp.fit(X, y, ops=OPS, generations=10, threads=1)
    path = tmp_path / "f.json"
    front.save(path)
    again = lgp.load_front(path)
    assert again.data == json.loads(json.dumps(front.data))
    assert again.source == str(path)
    (tmp_path / "bad.json").write_text('{"format": "lgp-front/1", "members": 3}')
    with pytest.raises(ValueError, match="bad.json"):
        lgp.load_front(tmp_path / "bad.json")


def test_sympy_is_the_formula(grid):
    sympy = pytest.importorskip("sympy")
    X, y = grid
    front = lgp.fit(X, y, inputs=["x", "y"], ops=OPS + ["min", "max", "saturate", "rcp"],
                    generations=40, threads=1, seed=4)
    for m in front:
        e = m.sympy()
        f = sympy.lambdify([sympy.Symbol("x", real=True), sympy.Symbol("y", real=True)], e,
                           "math")
        got = np.array([float(f(a, b)) for a, b in X])
        assert np.allclose(got, m.predict(X, double_precision=True), rtol=1e-4, atol=1e-5), \
            m.formula


def test_data_presets():
    t = lgp.data("dfg", size=8, cache_dir="-")
    assert t.inputs == ["mu", "r"] and t.outputs == ["A", "B"]
    assert t.X.shape == (64, 2) and t.y.shape == (64, 2)
    assert np.all((t.y >= 0) & (t.y <= 1)) and np.all(t.y.sum(axis=1) <= 1 + 1e-9)
    with pytest.raises(ValueError, match="scene"):
        lgp.data("nope")
    with pytest.raises(ValueError, match="size"):
        lgp.data("dfg", size=1)


def test_exhaustive_certificate_in_the_front(grid, tmp_path):
    # search.exhaustive: every expression of <= 4 operators over these ops is fitted first;
    # the exact one seeds the search, and the front carries the certificate.
    X, y = grid
    front = lgp.fit(X, y, inputs=["x", "y"], ops=OPS, generations=3, threads=2,
                    search={"exhaustive": {"max_ops": 4, "seconds": 300,
                                           "ops": ["mul", "mad", "square", "exp2"]}})
    cert = front.data["exhaustive"]
    assert cert["complete_ops"] == 4 and cert["seeded"] >= 1
    assert [b["max_ops"] for b in cert["best"]] == [1, 2, 3, 4]
    assert cert["best"][3]["error"] < 1e-6 and cert["best"][2]["error"] > 1e-3
    assert front.best().error < 1e-6  # three generations: the seed did it
    # `lgp front` prints the certificate; a control character in a recorded formula (a
    # tampered file) is never printed.
    cli = os.environ.get("LGP_CLI")
    if cli:
        path = tmp_path / "f.json"
        front.data["exhaustive"]["best"][0]["formula"] = "f = x\x1b[2J"
        front.save(path)
        out = subprocess.run([cli, "front", str(path)], capture_output=True, text=True,
                             check=True).stdout
        assert "exhaustive enumeration" in out and "<= 4 ops: error" in out
        assert "<= 1 ops" not in out and "\x1b" not in out


def test_html_view_escapes_names():
    g = np.linspace(0, 1, 8)
    X = np.stack([g, g[::-1]], axis=1)
    front = lgp.fit(X, X[:, 0] * 2, inputs=["<img src=x onerror=alert(1)>", "b"],
                    outputs=["y"], generations=5, threads=1)
    page = front._repr_html_()
    assert "<img" not in page and "&lt;img" in page
    assert page.count("<tr>") == len(front) + 1


SMALL_AND_LONG_ISLANDS = {"profiles": [{"max_length": 6, "constants": 2, "weight_rate": 0}, {}],
                          "topology": "by_profile"}


@pytest.mark.parametrize("program,variation,islands", [
    ({"genes": 3}, {}, {}),
    ({"constants": 12}, {"weight_rate": 0.3, "weight_min_length": 0}, {}),
    ({"genes": 2, "constants": 12}, {"weight_rate": 0.3, "weight_min_length": 0}, {}),
    ({"constants": 12}, {"weight_rate": 0.3, "weight_min_length": 0}, SMALL_AND_LONG_ISLANDS),
])
def test_output_layer_and_weights_predict_what_was_scored(grid, program, variation, islands):
    # The search-4 representations through the module: the layer is materialised (one
    # output), predict() reproduces the recorded float32 metrics, the double path agrees, and
    # the exhaustive enumeration seeds the run under the layer too (and the small islands of
    # a run with island profiles).
    X, y = grid
    front = lgp.fit(X, y, inputs=["x", "y"], ops=OPS, generations=25, threads=1, seed=4,
                    program={"max_length": 16, **program},
                    search={"population": 96, "linear_scaling": True, "variation": variation,
                            "islands": islands,
                            "exhaustive": {"max_ops": 2, "seconds": 20}})
    assert front.data["exhaustive"]["seeded"] >= 1
    assert all(lvl["error"] > 0 for lvl in front.data["exhaustive"]["best"])
    assert len(front) >= 3
    for m in front:
        p = m.predict(X)
        rec = m.metrics[front.outputs[0]]
        rmse = float(np.sqrt(np.mean((p - y) ** 2)))
        assert rmse == pytest.approx(rec["rmse"], rel=1e-5, abs=1e-9), m.formula
        d = m.predict(X, double_precision=True)
        assert np.allclose(p, d, rtol=1e-4, atol=1e-5), m.formula
