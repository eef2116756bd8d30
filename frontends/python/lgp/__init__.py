"""lgp: symbolic regression for cheap, accurate shader formulas, from Python.

    import lgp
    dfg = lgp.data("dfg", size=32)                      # ground truth, double precision
    front = lgp.fit(dfg, ops=["add", "mul", "mad", "exp2", "rcp"], seconds=60)
    m = front.best(max_cost=15)                         # most accurate member this cheap
    print(m.formula)
    print(m.emit("hlsl"))

The same engine, configs, checks and front format as the ``lgp`` command line (``lgp run``
writes what :func:`fit` returns; :func:`load_front` reads it; :meth:`Member.emit` prints what
``lgp emit`` prints). :class:`Regressor` is a scikit-learn estimator; :class:`Daemon` talks to
lgpd.
"""

from . import _lgp
from ._daemon import Daemon, DaemonError
from ._fit import Table, data, fit
from ._front import Front, Member, load_front
from ._sklearn import Regressor

#: The languages :meth:`Member.emit` writes, as ``lgp emit --lang`` names them.
languages = tuple(name for name, _title in _lgp.languages)

__all__ = ["Daemon", "DaemonError", "Front", "Member", "Regressor", "Table", "data", "fit",
           "languages", "load_front"]
__version__ = "0.1.0"
