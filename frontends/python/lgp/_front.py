"""Fronts: the Pareto front of a search as Python objects.

A :class:`Front` holds exactly the front JSON that ``lgp run`` writes (format ``lgp-front/1``,
see ``lgp/include/lgp/io/result.hpp``); :class:`Member` is a view of one of its members.
Predictions run the engine's float32 interpreter and code comes from the same emitters as
``lgp emit``.
"""

import html
import json
import math
import os
import tempfile

import numpy as np

from . import _lgp


class Member:
    """One formula of a front: its objectives, its formula, predictions and exported code."""

    def __init__(self, front, index):
        self._front = front
        self.index = index

    @property
    def _json(self):
        return self._front.data["members"][self.index]

    @property
    def error(self):
        """The searched error objective (the config's metric, combined over outputs)."""
        return self._json["error"]

    @property
    def cost(self):
        """Cost under the run's cost model (or the measured cost where the search used it)."""
        return self._json["cost"]

    @property
    def discontinuity(self):
        """Weighted count of piecewise operators (min, max, abs, saturate, select)."""
        return self._json["discontinuity"]

    @property
    def cost_by_target(self):
        """Modelled cost per GPU target, e.g. ``{"gpu-generic": 8.5, "rdna": 8.25, ...}``."""
        return dict(self._json.get("cost_by_target", {}))

    @property
    def cost_measured(self):
        """Measured AMD ISA statistics per GPU family where the run measured them, else None."""
        return self._json.get("cost_measured")

    @property
    def formula(self):
        """The whole program as one readable formula, e.g. ``B = exp2(-7*mu - 4*r^2)``."""
        return self._json["formula"]

    @property
    def expressions(self):
        """Per output name, its expression standing alone (its temporaries first)."""
        return {o["name"]: o["expression"] for o in self._json["outputs"]}

    @property
    def metrics(self):
        """Per output name, the float32 metrics (rmse, max_abs, mae, mean_rel, r2)."""
        return {o["name"]: dict(o["float32"]) for o in self._json["outputs"]}

    @property
    def program(self):
        """The bytecode (``code``, ``constants``, ``outputs``), as in the front JSON."""
        return self._json["program"]

    def predict(self, X, double_precision=False):
        """Evaluates the member on the rows of ``X`` (rows x the front's inputs).

        Uses the float32 interpreter the search scored with (``double_precision=True``: the
        double reference path). Returns shape ``(rows,)`` for one output, else
        ``(rows, outputs)``.
        """
        X = _as_rows(X, len(self._front.inputs))
        out = _lgp.predict(self._front.json_text, self.index, X, bool(double_precision))
        return out[:, 0] if out.shape[1] == 1 else out

    def emit(self, lang="hlsl", *, name="lgp_fit", precision="float", fast=False,
             pow_rewrites=True, domain_rewrites=True, exact_math=False, header=True,
             helpers=True, measure=True):
        """The member as HLSL, GLSL or C++ source, exactly as ``lgp emit`` writes it.

        The keywords are ``lgp emit``'s options (``fast=True`` is ``--fast``,
        ``header=False`` is ``--no-header``, ``measure=False`` is ``--no-measure``). For a
        front read with :func:`load_front`, the text equals
        ``lgp emit PATH --member INDEX --lang LANG`` byte for byte.
        """
        if not _lgp.has_emit:
            raise RuntimeError("this lgp was built without the emit library (LGP_WITH_EMIT=OFF)")
        return _lgp.emit(self._front.json_text, self.index, str(lang), self._front.source,
                         str(name), str(precision), bool(fast), bool(pow_rewrites),
                         bool(domain_rewrites), bool(exact_math), bool(header), bool(helpers),
                         bool(measure))

    def sympy(self):
        """The formula as a SymPy expression (a dict per output name for several outputs).

        Needs SymPy (Debian: python3-sympy). Temporaries are substituted; protected operators
        become their plain mathematical form (1/x, log2(x) as log(x, 2)).
        """
        from ._sympy import formula_to_sympy

        exprs = formula_to_sympy(self.formula, self._front.inputs, self._front.outputs)
        return exprs[self._front.outputs[0]] if len(exprs) == 1 else exprs

    def __repr__(self):
        return (f"Member({self.index}: error={self.error:.4g}, cost={self.cost:g}, "
                f"discontinuity={self.discontinuity:g}, {self.formula!r})")


class Front:
    """A search's Pareto front: members sorted by cost, then error.

    ``data`` is the front JSON as a dict (what ``lgp run`` writes); ``source`` names where it
    came from (a file path for :func:`load_front`, ``"lgp.fit"`` for a fit) and is the source
    line of emitted code.
    """

    def __init__(self, data, source="lgp.fit"):
        if not isinstance(data, dict) or data.get("format") != "lgp-front/1":
            raise ValueError("front: not an lgp-front/1 document")
        self.data = data
        self.source = str(source)
        self.json_text = json.dumps(data)
        self.interrupted = False

    @property
    def members(self):
        """Every member, cheapest first."""
        return [Member(self, i) for i in range(len(self.data["members"]))]

    def __len__(self):
        return len(self.data["members"])

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [Member(self, i) for i in range(len(self))[index]]
        n = len(self)
        if not isinstance(index, (int, np.integer)) or not -n <= index < n:
            raise IndexError(f"member: index {index!r} is outside the front's {n} members")
        return Member(self, int(index) % n)

    def __iter__(self):
        return iter(self.members)

    @property
    def inputs(self):
        """Input names, in the order of X's columns."""
        return self._names("inputs")

    @property
    def outputs(self):
        """Output names."""
        return self._names("outputs")

    def _names(self, key):
        # A front is a file (or a daemon's answer): a missing field is a ValueError naming it.
        table = self.data.get("table")
        names = table.get(key) if isinstance(table, dict) else None
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            raise ValueError(f"front: /table/{key}: missing, or not a list of names")
        return list(names)

    @property
    def config(self):
        """The resolved run config of the search."""
        return self.data["config"]

    @property
    def progress(self):
        """Generations, evaluations, elapsed time and stop reason of the search."""
        return self.data["progress"]

    @property
    def references(self):
        """The config's reference formulas, scored on the run's table (may be empty)."""
        return self.data.get("references", [])

    def best(self, max_cost=None, cost_target=None):
        """The most accurate member, or the most accurate with cost <= ``max_cost``.

        ``cost_target`` picks the cost column ("gpu-generic", "nvidia", "gcn", "rdna", "cpu";
        default: the run's model). Raises ValueError when no member is that cheap.
        """
        members = self.members
        if max_cost is not None:
            members = [m for m in members if self._cost(m, cost_target) <= max_cost]
            if not members:
                cheapest = min(self._cost(m, cost_target) for m in self.members)
                raise ValueError(f"max_cost: no member costs <= {max_cost} "
                                 f"(the cheapest costs {cheapest:g})")
        return min(members, key=lambda m: (m.error, self._cost(m, cost_target)))

    def cheapest(self, max_error=None, cost_target=None):
        """The cheapest member, or the cheapest with error <= ``max_error``."""
        members = self.members
        if max_error is not None:
            members = [m for m in members if m.error <= max_error]
            if not members:
                best = min(m.error for m in self.members)
                raise ValueError(f"max_error: no member has error <= {max_error} "
                                 f"(the most accurate has {best:.4g})")
        return min(members, key=lambda m: (self._cost(m, cost_target), m.error))

    def predict(self, X, member=None, double_precision=False):
        """Predictions of ``member`` (an index or a Member; default: the most accurate)."""
        m = self.best() if member is None else (
            member if isinstance(member, Member) else self[member])
        return m.predict(X, double_precision=double_precision)

    def save(self, path):
        """Writes the front JSON (atomically) to ``path``; ``lgp front``/``lgp emit`` read it."""
        path = os.fspath(path)
        folder = os.path.dirname(os.path.abspath(path))
        fd, tmp = tempfile.mkstemp(prefix=".lgp-front-", dir=folder)
        try:
            with os.fdopen(fd, "w") as f:
                json.dump(self.data, f, indent=2)
                f.write("\n")
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, path)
        except BaseException:
            if os.path.exists(tmp):
                os.unlink(tmp)
            raise
        self.source = path

    def _cost(self, member, target):
        if target is None:
            return member.cost
        costs = member.cost_by_target
        if target not in costs:
            raise ValueError(f"cost_target: '{target}' is not one of {sorted(costs)}")
        return costs[target]

    def __repr__(self):
        lines = [f"Front({len(self)} members, inputs {self.inputs}, outputs {self.outputs})"]
        for m in self.members:
            err = m.error if math.isfinite(m.error) else float("nan")
            lines.append(f"  {m.index:3d}  cost {m.cost:7.3g}  error {err:.4g}  {m.formula}")
        return "\n".join(lines)

    def _repr_html_(self):
        """The front as an HTML table, for notebooks (every text escaped: column names are
        data)."""
        head = "".join(f"<th>{h}</th>" for h in ("#", "cost", "error", "discontinuity",
                                                  "formula"))
        rows = "".join(
            f"<tr><td>{m.index}</td><td>{m.cost:g}</td><td>{m.error:.4g}</td>"
            f"<td>{m.discontinuity:g}</td><td><code>{html.escape(m.formula)}</code></td></tr>"
            for m in self.members)
        caption = html.escape(f"{len(self)} members; inputs {', '.join(self.inputs)}; "
                              f"outputs {', '.join(self.outputs)}")
        return (f"<table><caption>{caption}</caption><thead><tr>{head}</tr></thead>"
                f"<tbody>{rows}</tbody></table>")

    def __getstate__(self):
        return {"data": self.data, "source": self.source, "interrupted": self.interrupted}

    def __setstate__(self, state):
        self.__init__(state["data"], state["source"])
        self.interrupted = state["interrupted"]


def load_front(path):
    """Reads a front file written by ``lgp run``, lgpd or :meth:`Front.save`.

    The file is checked as ``lgp front`` checks it; a bad file raises ValueError naming the
    file and the field.
    """
    path = os.fspath(path)
    return Front(json.loads(_lgp.read_front(path)), source=path)


def _as_rows(X, columns):
    """X as a C-contiguous float64 array of shape (rows, columns)."""
    X = np.asarray(X, dtype=np.float64)
    if X.ndim == 1 and columns == 1:
        X = X.reshape(-1, 1)
    if X.ndim != 2:
        raise ValueError(f"X: must be a 2-D array of rows x {columns} inputs "
                         f"(got {X.ndim} dimensions)")
    if X.shape[1] != columns:
        raise ValueError(f"X: has {X.shape[1]} columns, the front has {columns} inputs")
    return np.ascontiguousarray(X)
