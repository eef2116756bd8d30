"""lgp.Regressor as a scikit-learn estimator."""

import numpy as np
import pytest

import lgp

sklearn = pytest.importorskip("sklearn")
from sklearn.utils.estimator_checks import check_estimator  # noqa: E402


def test_passes_sklearn_estimator_checks():
    # A small budget: the checks fit some 60 times.
    check_estimator(lgp.Regressor(generations=8, population=40, max_length=8))


def test_regressor_fits_and_chooses():
    rng = np.random.default_rng(0)
    X = rng.uniform(0, 1, size=(300, 2))
    y = np.exp2(-7 * X[:, 0] - 4 * X[:, 1] ** 2)
    r = lgp.Regressor(ops=["add", "sub", "mul", "mad", "neg", "square", "exp2"],
                      generations=150, random_state=1)
    r.fit(X, y)
    assert r.score(X, y) > 0.999
    assert r.n_features_in_ == 2 and r.formula_ == r.model_.formula
    cheap = lgp.Regressor(**{**r.get_params(), "select": "cost", "max_error": 0.05}).fit(X, y)
    assert cheap.model_.cost <= r.model_.cost and cheap.model_.error <= 0.05
    knee = r.set_params(select="knee").fit(X, y)
    assert knee.model_.index in range(len(knee.front_))
    with pytest.raises(ValueError, match="select"):
        lgp.Regressor(select="median").fit(X, y)
    with pytest.raises(ValueError, match="random_state"):
        lgp.Regressor(random_state=-3, generations=2).fit(X, y)


def test_seconds_alone_is_the_budget():
    # Regressor(seconds=S) searches S seconds: the default of 100 generations (about a second
    # on this table) applies only when no budget is given, and then it is the stop.
    rng = np.random.default_rng(3)
    X = rng.uniform(0, 1, size=(60, 2))
    y = np.exp2(-3 * X[:, 0]) * X[:, 1] + rng.normal(0, 1e-3, 60)
    small = dict(population=20, max_length=6, random_state=1)
    timed = lgp.Regressor(seconds=1.5, **small).fit(X, y)
    assert timed.get_params()["generations"] is None
    assert timed.front_.progress["stop_reason"] == "wall_time"
    assert timed.front_.progress["generation"] > 100
    default = lgp.Regressor(**small).fit(X, y)
    assert default.front_.progress["stop_reason"] == "generations"
    assert default.front_.progress["generation"] == 100
    # A budget in config is the budget: the default 100 generations do not cap it.
    by_config = lgp.Regressor(**small, config={"search": {"generations": 130}}).fit(X, y)
    assert by_config.front_.progress["generation"] == 130


def test_structured_start_only_when_asked():
    # The Regressor is for exact recovery: the structured start's inexact polynomials are off
    # unless its config names search.structured (then the engine's defaults apply).
    rng = np.random.default_rng(3)
    X = rng.uniform(0, 1, size=(60, 2))
    y = np.exp2(-3 * X[:, 0]) * X[:, 1]
    small = dict(generations=3, population=20, max_length=6, random_state=1)
    plain = lgp.Regressor(**small).fit(X, y)
    assert "structured" not in plain.front_.progress
    asked = lgp.Regressor(**small, config={"search": {"structured": {}}}).fit(X, y)
    assert asked.front_.progress["structured"]["fits"] > 0
    assert asked.get_params()["config"] == {"search": {"structured": {}}}


def test_pipeline_and_grid_search():
    from sklearn.model_selection import cross_val_score
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    rng = np.random.default_rng(1)
    X = rng.uniform(-1, 1, size=(200, 3))
    y = 3 * X[:, 0] * X[:, 1] + X[:, 2]
    model = make_pipeline(StandardScaler(), lgp.Regressor(generations=60, random_state=2))
    scores = cross_val_score(model, X, y, cv=3)
    assert np.all(scores > 0.9), scores


def _feynman_bench():
    import importlib.util
    import os
    path = os.path.join(os.path.dirname(__file__), "..", "..", "bench", "recovery",
                        "feynman_regressor.py")
    spec = importlib.util.spec_from_file_location("feynman_regressor", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_feynman_bench_equations_and_exact_recovery():
    fr = _feynman_bench()
    rng = np.random.default_rng(3)
    for name, (_, spec, f) in fr.EQUATIONS.items():
        y = f(*fr.draw(spec, 500, rng).T)
        assert np.all(np.isfinite(y)) and np.ptp(y) > 0, name
    y = rng.uniform(1, 2, 100)
    assert fr.r2(y, y) == 1.0
    assert fr.r2(y, y + 1e-5 * rng.standard_normal(100)) < fr.EXACT
    # The benchmark's own run on the easiest equation: mu * Nn, found exactly in 3 s, and
    # the 3 s were its budget (not a generation count).
    r = fr.run_one(lgp, "I.12.1", 1, 3.0)
    assert r["exact"] and r["near"], r
    assert r["stop"] == "wall_time" and fr.stops([r, r]) == "wall_time 2", r
