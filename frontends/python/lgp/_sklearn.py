"""lgp.Regressor: a scikit-learn estimator around lgp.fit (works without scikit-learn too)."""

import numbers

import numpy as np

from ._fit import fit as _fit

try:  # scikit-learn is optional: with it, Regressor is a real sklearn estimator.
    from sklearn.base import BaseEstimator, RegressorMixin
    from sklearn.utils.validation import check_is_fitted

    _HAVE_SKLEARN = True
except ImportError:  # pragma: no cover - exercised where python3-sklearn is missing
    _HAVE_SKLEARN = False

    class BaseEstimator:  # the parameter protocol scikit-learn defines
        def get_params(self, deep=True):
            return {k: getattr(self, k) for k in Regressor._PARAMS}

        def set_params(self, **params):
            for k, v in params.items():
                if k not in Regressor._PARAMS:
                    raise ValueError(f"{k}: not a parameter of Regressor")
                setattr(self, k, v)
            return self

    class RegressorMixin:
        def score(self, X, y, sample_weight=None):
            y = np.asarray(y, dtype=np.float64)
            p = self.predict(X)
            w = np.ones_like(y) if sample_weight is None else np.asarray(sample_weight)
            ss_res = np.sum(w * (y - p) ** 2)
            ss_tot = np.sum(w * (y - np.average(y, weights=w)) ** 2)
            return 1 - ss_res / ss_tot if ss_tot > 0 else 0.0

    def check_is_fitted(est, attributes=None):
        if not hasattr(est, "front_"):
            raise ValueError("Regressor: not fitted; call fit first")


_SELECT = ("error", "cost", "knee")
_DEFAULT_GENERATIONS = 100


class Regressor(RegressorMixin, BaseEstimator):
    """Symbolic regression with lgp, as a scikit-learn regressor.

    Parameters: ``ops`` (operator names; None = the engine's default set), ``generations``
    and ``seconds`` (budgets: ``seconds`` given alone is the only budget; with neither, here
    or as ``search.generations`` / ``search.wall_time_s`` in ``config``, 100 generations),
    ``population``,
    ``max_length`` (opcodes per program), ``threads`` (1 by default, so that a fit is
    reproducible for a given ``random_state``; 0 = every core), ``random_state`` (the seed),
    ``linear_scaling`` (fit a*f + b in closed form), ``error`` (the objective: rmse, mae,
    max_abs, mean_rel), ``select`` (which front member ``predict`` uses: "error" = the most
    accurate, "cost" = the cheapest with error <= ``max_error``, "knee" = the member past
    which a unit of cost buys the least error), ``max_cost`` (with "error": only members this
    cheap), ``max_error``, ``config`` (a dict of further run-config sections) and
    ``progress`` (as lgp.fit).

    Unlike lgp.fit, the Regressor runs without the structured accurate end
    (``search.structured``) unless ``config`` names it: its least-squares polynomials give a
    close but inexact fit at generation 0, which then takes the search's effort from the exact
    formula (AI Feynman equations at 30 s, bench/results/feynman_short). Pass
    ``config={"search": {"structured": {}}}`` to have it, as on smooth rendering tables.

    After ``fit``: ``front_`` (the whole :class:`lgp.Front`), ``model_`` (the chosen
    member), ``formula_`` and ``n_features_in_``.
    """

    _PARAMS = ("ops", "generations", "seconds", "population", "max_length", "threads",
               "random_state", "linear_scaling", "error", "select", "max_cost", "max_error",
               "config", "progress")

    def __init__(self, ops=None, generations=None, seconds=None, population=200, max_length=24,
                 threads=1, random_state=None, linear_scaling=True, error="rmse",
                 select="error", max_cost=None, max_error=None, config=None, progress=False):
        self.ops = ops
        self.generations = generations
        self.seconds = seconds
        self.population = population
        self.max_length = max_length
        self.threads = threads
        self.random_state = random_state
        self.linear_scaling = linear_scaling
        self.error = error
        self.select = select
        self.max_cost = max_cost
        self.max_error = max_error
        self.config = config
        self.progress = progress

    def _more_tags(self):
        return {"requires_y": True}

    def fit(self, X, y, sample_weight=None):
        """Searches on X (rows x features) and y (rows); returns self."""
        if self.select not in _SELECT:
            raise ValueError(f"select: must be one of {', '.join(_SELECT)} (got {self.select!r})")
        X, y = self._check_Xy(X, y)
        if sample_weight is not None:
            sw = np.asarray(sample_weight, dtype=np.float64)
            if sw.ndim == 0:
                sw = np.full(X.shape[0], float(sw))
            if sw.shape != (X.shape[0],):
                raise ValueError(f"sample_weight: shape {sw.shape}, expected ({X.shape[0]},)")
            if not np.all(np.isfinite(sw)) or np.any(sw < 0):
                raise ValueError("sample_weight: must be finite and >= 0")
            # Rows of weight 0 carry nothing: left out, the search is the one on the rest.
            keep = sw > 0
            X, y, sw = X[keep], y[keep], sw[keep]
            if not np.any(sw):
                raise ValueError("sample_weight: every weight is 0")
            sample_weight = None if np.all(sw == sw[0]) else sw
        seed = self._seed()
        # A default of 100 generations would cut a ``seconds`` budget short (100 generations
        # take about a second), so it applies only when no budget is given, here or in config.
        sections = dict(self.config or {})
        search = {**sections.get("search", {}), "population": self.population,
                  "linear_scaling": bool(self.linear_scaling)}
        generations = self.generations
        if generations is None and self.seconds is None and not (
                {"generations", "wall_time_s"} & set(search)):
            generations = _DEFAULT_GENERATIONS
        search.setdefault("structured", {"max_degree": 0})
        sections["program"] = {**sections.get("program", {}), "max_length": self.max_length}
        sections["search"] = search
        sections["objectives"] = {**sections.get("objectives", {}), "error": self.error}
        self.front_ = _fit(X, y, inputs=[f"x{i}" for i in range(X.shape[1])], outputs=["y"],
                           ops=self.ops, seconds=self.seconds, generations=generations,
                           threads=self.threads, seed=seed, sample_weight=sample_weight,
                           progress=self.progress, **sections)
        self.model_ = self._choose(self.front_)
        self.formula_ = self.model_.formula
        self.n_features_in_ = X.shape[1]
        return self

    def predict(self, X):
        """The chosen member's predictions (float32 interpreter), shape (rows,)."""
        check_is_fitted(self, "front_")
        X = self._check_X(X)
        return self.model_.predict(X)

    def _seed(self):
        rs = self.random_state
        if rs is None:
            return 1
        if isinstance(rs, numbers.Integral) and not isinstance(rs, bool):
            if rs < 0:
                raise ValueError(f"random_state: must be >= 0 (got {rs})")
            return int(rs)
        if isinstance(rs, np.random.RandomState):
            return int(rs.randint(0, 2**31 - 1))
        raise ValueError(f"random_state: must be None, an integer or a RandomState (got {rs!r})")

    def _choose(self, front):
        members = front.members
        if self.select == "cost":
            return front.cheapest(max_error=self.max_error)
        if self.select == "knee":
            return _knee(members)
        return front.best(max_cost=self.max_cost)

    def _check_Xy(self, X, y):
        if _HAVE_SKLEARN:
            return self._validate_data(X, y, y_numeric=True, dtype=np.float64)
        X = np.asarray(X, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64).ravel()
        if X.ndim != 2 or not np.all(np.isfinite(X)) or not np.all(np.isfinite(y)):
            raise ValueError("X, y: need a finite 2-D X and a finite y")
        return X, y

    def _check_X(self, X):
        if _HAVE_SKLEARN:
            return self._validate_data(X, reset=False, dtype=np.float64)
        X = np.asarray(X, dtype=np.float64)
        if X.ndim != 2 or X.shape[1] != self.n_features_in_:
            raise ValueError(f"X: expected {self.n_features_in_} columns")
        return X


def _knee(members):
    """The member where the front bends: farthest below the line from the cheapest member to
    the most accurate one, in (cost, log error)."""
    pts = [(m.cost, np.log10(max(m.error, 1e-30)), m) for m in members]
    (c0, e0, m0), (c1, e1, _) = pts[0], min(pts, key=lambda p: p[1])
    if c1 == c0:
        return m0
    best, best_d = m0, 0.0
    for c, e, m in pts:
        line = e0 + (e1 - e0) * (c - c0) / (c1 - c0)
        if line - e > best_d:
            best, best_d = m, line - e
    return best if best_d > 0 else min(pts, key=lambda p: p[1])[2]
