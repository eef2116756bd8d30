"""Run configs from Python arguments: the same JSON ``lgp run`` reads, checked by the engine."""

import copy
import json
import math
import numbers
import os

from . import _lgp

# Top-level sections of a run config (lgp/include/lgp/config/config.hpp); `output` is not
# among them because a fit keeps its front in memory.
SECTIONS = ("data", "program", "objectives", "search", "eval", "references", "mpi")


def merge(base, extra):
    """Deep merge of config dicts: ``extra``'s values win, dicts are merged key by key."""
    out = copy.deepcopy(base)
    for k, v in extra.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def load(config):
    """A config given as a dict, a JSON file path or None: (dict, directory of its paths)."""
    if config is None:
        return {}, os.getcwd()
    if isinstance(config, dict):
        return copy.deepcopy(config), os.getcwd()
    if isinstance(config, (str, os.PathLike)):
        path = os.path.abspath(os.fspath(config))
        try:
            with open(path, encoding="utf-8") as f:
                data = json.load(f)
        except OSError as e:
            raise ValueError(f"config: {path}: cannot read ({e.strerror})") from None
        except json.JSONDecodeError as e:
            raise ValueError(f"config: {path}: not JSON (line {e.lineno}, column {e.colno})") \
                from None
        if not isinstance(data, dict):
            raise ValueError(f"config: {path}: must be a JSON object")
        return data, os.path.dirname(path)
    raise ValueError(f"config: expected a dict or a JSON file path, got {type(config).__name__}")


def build(config=None, sections=None, *, ops=None, seconds=None, generations=None,
          threads=None, seed=None):
    """The run config of a fit: ``config`` (dict or file), then the keyword sections, then the
    shortcuts. Returns (dict, base directory). Unknown sections raise ValueError naming them."""
    cfg, base_dir = load(config)
    cfg.pop("output", None)
    for key, value in (sections or {}).items():
        if key not in SECTIONS:
            raise ValueError(f"{key}: not a config section or an argument of lgp.fit (sections: "
                             f"{', '.join(SECTIONS)})")
        if key == "references":
            cfg[key] = copy.deepcopy(value)
        elif not isinstance(value, dict):
            raise ValueError(f"{key}: must be a dict (the /{key} section of a run config)")
        else:
            cfg = merge(cfg, {key: value})
    search = cfg.setdefault("search", {})
    if ops is not None:
        if isinstance(ops, str) or not all(isinstance(o, str) for o in ops):
            raise ValueError("ops: must be a list of operator names, e.g. ['add', 'mul', 'exp2']")
        cfg.setdefault("program", {})["ops"] = list(ops)
    if seconds is not None:
        search["wall_time_s"] = _number("seconds", seconds, 0)
        # A time budget alone: no generation limit unless one is given as well.
        if generations is None and "generations" not in search:
            search["generations"] = 0
    if generations is not None:
        search["generations"] = _integer("generations", generations, 0)
    if threads is not None:
        search["threads"] = _integer("threads", threads, 0)
    if seed is not None:
        search["seed"] = _integer("seed", seed, 0)
    return cfg, base_dir


def check(cfg, base_dir):
    """Raises ValueError with the engine's message (naming the JSON path) if ``cfg`` is bad."""
    why = _lgp.check_config(dumps(cfg), base_dir)
    if why:
        raise ValueError(why)


def dumps(doc):
    """``doc`` as JSON text. JSON has no NaN or infinity (the engine reads "Infinity" as an
    invalid literal): the first non-finite number is a ValueError naming its path."""
    try:
        return json.dumps(doc, allow_nan=False)
    except ValueError:
        path = _non_finite(doc, "")
        if path is None:
            raise
        where, v = path
        raise ValueError(f"{where or '/'}: must be a finite number (got {v!r})") from None


def _non_finite(v, path):
    if isinstance(v, float) and not math.isfinite(v):
        return path, v
    if isinstance(v, dict):
        items = ((f"{path}/{k}", x) for k, x in v.items())
    elif isinstance(v, (list, tuple)):
        items = ((f"{path}/{i}", x) for i, x in enumerate(v))
    else:
        return None
    for p, x in items:
        found = _non_finite(x, p)
        if found is not None:
            return found
    return None


def _integer(name, v, lo):
    if isinstance(v, bool) or not isinstance(v, numbers.Integral) or v < lo:
        raise ValueError(f"{name}: must be an integer >= {lo} (got {v!r})")
    return int(v)


def _number(name, v, lo):
    if isinstance(v, bool) or not isinstance(v, numbers.Real) or not v >= lo or \
            not math.isfinite(v):
        raise ValueError(f"{name}: must be a finite number >= {lo} (got {v!r})")
    return float(v)
