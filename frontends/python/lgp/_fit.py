"""lgp.fit: a search from numpy arrays, a table file or a scene; lgp.data: ground-truth tables."""

import copy
import json
import os
import sys
import warnings

import numpy as np

from . import _config, _lgp
from ._front import Front
from ._progress import Reporter


class Table:
    """A table of samples: ``X`` (rows x inputs), ``y`` (rows x outputs) and their names.

    :func:`data` returns one; :func:`fit` takes one in place of ``X``.
    """

    def __init__(self, X, y, inputs, outputs, meta=None):
        self.X = np.asarray(X, dtype=np.float64)
        self.y = np.asarray(y, dtype=np.float64)
        self.inputs = list(inputs)
        self.outputs = list(outputs)
        self.meta = meta or {}

    def __len__(self):
        return self.X.shape[0]

    def column(self, name):
        """One column by name (an input or an output)."""
        if name in self.inputs:
            return self.X[:, self.inputs.index(name)]
        if name in self.outputs:
            return self.y[:, self.outputs.index(name)]
        raise KeyError(f"{name}: not a column (inputs {self.inputs}, outputs {self.outputs})")

    def __repr__(self):
        return f"Table({len(self)} rows, inputs {self.inputs}, outputs {self.outputs})"


# Shorthands for the bundled effects (datasets/README.md has the whole scene format).
_PRESETS = {
    "dfg": {
        "material": {"ndf": "ggx", "visibility": "smith-correlated",
                     "fresnel": {"model": "schlick", "f90": 1.0}, "roughness": "perceptual"},
        "light": {"type": "environment"}, "outputs": ["A", "B"],
        "grid": {"mu": [1 / 64, 1.0], "r": [0.0, 1.0]}},
    "energy": {
        "material": {"visibility": "smith-correlated", "fresnel": "none",
                     "roughness": "perceptual"},
        "light": {"type": "environment"}, "outputs": ["E", "one_minus_E", "E_avg"],
        "grid": {"mu": [0.0, 1.0], "r": [0.0, 1.0]}},
    "zh": {
        "material": {"diffuse": "disney"}, "light": {"type": "environment"},
        "outputs": ["ZH0", "ZH1", "ZH2", "ZH1_over_ZH0", "ZH2_over_ZH0", "beta"],
        "grid": {"mu": [0.0, 1.0], "r": [0.0, 1.0]}},
    "normalization": {
        "material": {"visibility": "smith-correlated", "roughness": "perceptual"},
        "light": {"type": "sphere", "size": "tan_half_theta_s", "range": [0.0, 0.6],
                  "softmin_s": -3, "incidence": "normal"},
        "outputs": ["N"], "grid": {"r": [0.1, 1.0], "tan_half_theta_s": None}},
}


def data(scene, size=32, *, abs_error=None, cache_dir=None, threads=0):
    """A ground-truth table, computed in double precision by the datasets library (cached).

    ``scene``: a scene dict or scene JSON file (``lgp-scene/1``, see datasets/README.md), or
    one of the bundled effects: ``"dfg"`` (split-sum A, B over mu and r), ``"energy"``
    (Kulla-Conty E, 1 - E, E_avg), ``"zh"`` (Disney diffuse in zonal harmonics) or
    ``"normalization"`` (sphere-light normalization N). For a bundled effect, ``size`` is the
    grid's points per axis and ``abs_error`` the integration tolerance. ``cache_dir``: where
    tables are cached (default ``$LGP_CACHE_DIR`` or ``~/.cache/lgp``; ``"-"``: no cache).
    """
    if not _lgp.has_datasets:
        raise RuntimeError("this lgp was built without the datasets library")
    if isinstance(scene, str) and scene in _PRESETS:
        if isinstance(size, bool) or not isinstance(size, (int, np.integer)) or size < 2:
            raise ValueError(f"size: must be an integer >= 2 (got {size!r})")
        p = copy.deepcopy(_PRESETS[scene])
        grid = {}
        for name, rng in p.pop("grid").items():
            axis = {"count": int(size), "spacing": "edge"}
            if rng is not None:
                axis["range"] = rng
            grid[name] = axis
        doc = {"format": "lgp-scene/1", "name": f"{scene}-{size}", **p, "grid": grid}
        if abs_error is not None:
            doc["accuracy"] = {"abs_error": float(abs_error)}
    elif isinstance(scene, dict):
        doc = scene
    elif isinstance(scene, (str, os.PathLike)):
        path = os.fspath(scene)
        if not os.path.isfile(path):
            raise ValueError(f"scene: '{path}' is neither a scene file nor one of "
                             f"{', '.join(sorted(_PRESETS))}")
        with open(path, encoding="utf-8") as f:
            doc = json.load(f)
    else:
        raise ValueError(f"scene: expected a dict, a file or a name, got {type(scene).__name__}")
    cache = "" if cache_dir is None else os.fspath(cache_dir)
    inputs, outputs, X, Y, meta, note = _lgp.generate(_config.dumps(doc), cache, int(threads))
    if note:
        warnings.warn(note)
    return Table(X, Y, inputs, outputs, json.loads(meta))


def fit(X=None, y=None, *, inputs=None, outputs=None, ops=None, seconds=None, generations=None,
        threads=None, seed=None, sample_weight=None, table=None, scene=None, config=None,
        progress=None, progress_interval=1.0, **sections):
    """Runs a search and returns its :class:`Front`.

    The data, one of:

    * ``X`` (rows x inputs) and ``y`` (rows, or rows x outputs) as arrays; names from
      ``inputs``/``outputs`` (default ``x0, x1, ...`` and ``y`` or ``y0, y1, ...``; a pandas
      DataFrame or Series gives its column names);
    * a :class:`Table` (from :func:`data`) as ``X``;
    * ``table``: a CSV or ``lgp-table/1`` JSON file, or ``scene``: a scene file; ``inputs``
      and ``outputs`` then pick columns (default: the file's own roles);
    * ``config``: a run config (dict or JSON file, as ``lgp run`` reads) that names its data.

    The budget and the search: ``ops`` (operator names), ``seconds`` (wall time; alone, it is
    the only budget), ``generations``, ``threads`` (0 = every core), ``seed``. Any other
    section of a run config is a keyword taking a dict: ``program={"max_length": 24}``,
    ``objectives={"error": "max_abs"}``, ``search={"population": 800}``, ``references=[...]``.
    A bad value raises ValueError naming it, with the same message as ``lgp run``.

    ``progress``: None (automatic), True, False or a callable taking each progress dict, every
    ``progress_interval`` seconds. Ctrl-C stops the search after the current generation and
    returns the front found so far (``front.interrupted`` is then True); a second Ctrl-C
    raises KeyboardInterrupt.
    """
    cfg, base_dir = _config.build(config, sections, ops=ops, seconds=seconds,
                                  generations=generations, threads=threads, seed=seed)
    data_cfg = cfg.setdefault("data", {})
    arrays = None
    if isinstance(X, Table):
        if y is not None:
            raise ValueError("y: not used with a Table (its outputs are the targets)")
        inputs = inputs or X.inputs
        outputs = outputs or X.outputs
        X, y = X.X, X.y
    sources = [n for n, v in (("X", X), ("table", table), ("scene", scene)) if v is not None]
    if len(sources) > 1:
        raise ValueError(f"{sources[1]}: give the data once (also given: {sources[0]})")
    if X is not None:
        if y is None:
            raise ValueError("y: required with X")
        Xa, ya, inputs, outputs = _arrays(X, y, inputs, outputs)
        arrays = (Xa, ya)
        for k in ("path", "scene", "table"):
            data_cfg.pop(k, None)
        data_cfg["inputs"], data_cfg["outputs"] = inputs, outputs
        # Recorded in the front's config; the table itself lives only in this process.
        data_cfg["path"] = "(arrays given to lgp.fit)"
        weights = None
        if sample_weight is not None:
            weights = np.ascontiguousarray(
                np.asarray(sample_weight, dtype=np.float64).reshape(-1, 1))
    else:
        if sample_weight is not None:
            raise ValueError("sample_weight: only with X and y (a file names its weight column "
                             "in data.weights)")
        if table is not None or scene is not None:
            for k in ("path", "scene", "table"):
                data_cfg.pop(k, None)
            key = "path" if table is not None else "scene"
            data_cfg[key] = os.path.abspath(os.fspath(table if table is not None else scene))
        if inputs is not None:
            data_cfg["inputs"] = list(inputs)
        if outputs is not None:
            data_cfg["outputs"] = [outputs] if isinstance(outputs, str) else list(outputs)
        if not any(k in data_cfg for k in ("path", "scene")):
            raise ValueError("data: give X and y, a table, a scene, or a config that names its "
                             "data (data.path or data.scene)")
        weights = None
    reporter = Reporter(progress)
    if not (isinstance(progress_interval, (int, float)) and progress_interval >= 0):
        raise ValueError(f"progress_interval: must be a number >= 0 (got {progress_interval!r})")
    try:
        text, interrupted, note = _lgp.run(
            _config.dumps(cfg), base_dir, arrays[0] if arrays else None,
            arrays[1] if arrays else None, weights, reporter if reporter.active else None,
            float(progress_interval))
    finally:
        reporter.close()
    if note and reporter.active:
        print("lgp: " + note.replace("\n", "\nlgp: "), file=sys.stderr)
    front = Front(json.loads(text))
    front.interrupted = bool(interrupted)
    if interrupted:
        warnings.warn("lgp.fit: interrupted; returning the front found so far "
                      f"({len(front)} members)", RuntimeWarning, stacklevel=2)
    return front


def _names(given, default, count, what, taken=()):
    if isinstance(given, str):
        given = [given]
    names = list(given) if given is not None else default
    if names is None:
        # x0, x1, ...; y (or y0, y1, ...), and f where an input is already called y.
        stem = what if what == "x" or "y" not in taken else "f"
        names = [f"{stem}{i}" for i in range(count)] if count > 1 or what == "x" else [stem]
    if len(names) != count:
        raise ValueError(f"{'inputs' if what == 'x' else 'outputs'}: {len(names)} names for "
                         f"{count} columns")
    return [str(n) for n in names]


def _arrays(X, y, inputs, outputs):
    x_names = list(getattr(X, "columns", [])) or None
    y_names = list(getattr(y, "columns", [])) or None
    if y_names is None and getattr(y, "name", None) is not None and np.ndim(y) == 1:
        y_names = [y.name]
    try:
        Xa = np.asarray(X, dtype=np.float64)
        ya = np.asarray(y, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"X, y: not numeric arrays ({e})") from None
    if Xa.ndim == 1:
        Xa = Xa.reshape(-1, 1)
    if Xa.ndim != 2:
        raise ValueError(f"X: must be 2-D (rows x inputs), got {Xa.ndim} dimensions")
    if ya.ndim == 1:
        ya = ya.reshape(-1, 1)
    if ya.ndim != 2:
        raise ValueError(f"y: must be 1-D or 2-D (rows x outputs), got {ya.ndim} dimensions")
    if Xa.shape[0] != ya.shape[0]:
        raise ValueError(f"y: has {ya.shape[0]} rows, X has {Xa.shape[0]}")
    inputs = _names(inputs, x_names, Xa.shape[1], "x")
    outputs = _names(outputs, y_names, ya.shape[1], "y", inputs)
    return np.ascontiguousarray(Xa), np.ascontiguousarray(ya), inputs, outputs
