"""Progress of a running search: a line that rewrites itself in a terminal, a live text cell in a
notebook, or a user callback."""

import json
import math
import sys


def _fmt(e):
    return f"{e:.3g}" if isinstance(e, (int, float)) and math.isfinite(e) else "-"


def describe(p):
    """One line for a progress dict (the ``lgp run --status`` counters)."""
    levels = " ".join(f"c<={c:g}:{_fmt(e)}" for c, e in p.get("best_at_cost", []))
    return (f"gen {p['generation']}  evals {p['evaluations']}  {p['evals_per_s']:.3g} evals/s  "
            f"front {p['front_size']}  best {_fmt(p['best_error'])}" +
            (f" | {levels}" if levels else ""))


def _in_notebook():
    shell = sys.modules.get("IPython")
    if shell is None:
        return False
    try:
        ip = shell.get_ipython()
    except Exception:  # an IPython without a running shell
        return False
    return ip is not None and type(ip).__name__ == "ZMQInteractiveShell"


class Reporter:
    """Turns the engine's progress JSON into what ``progress`` asks for.

    ``progress``: None (automatic: a notebook cell in Jupyter, a rewriting line on a terminal,
    nothing otherwise), True (lines on stderr even when it is not a terminal), False (nothing),
    or a callable that receives each progress dict.
    """

    def __init__(self, progress):
        self._callback = None
        self._mode = "off"
        self._handle = None
        if callable(progress) and not isinstance(progress, bool):
            self._callback = progress
            self._mode = "callback"
        elif progress is None or progress is True:
            if _in_notebook():
                self._mode = "notebook"
            elif sys.stderr is not None and sys.stderr.isatty():
                self._mode = "terminal"
            elif progress is True:
                self._mode = "lines"
        elif progress is not False:
            raise ValueError("progress: must be None, True, False or a callable")

    @property
    def active(self):
        return self._mode != "off"

    def __call__(self, text):
        p = json.loads(text)
        if self._mode == "callback":
            self._callback(p)
        elif self._mode == "notebook":
            from IPython.display import display

            line = "lgp: " + describe(p)
            if self._handle is None:
                self._handle = display({"text/plain": line}, raw=True, display_id=True)
            else:
                self._handle.update({"text/plain": line}, raw=True)
        elif self._mode == "terminal":
            sys.stderr.write("\r\033[Klgp: " + describe(p))
            sys.stderr.flush()
        elif self._mode == "lines":
            sys.stderr.write("lgp: " + describe(p) + "\n")
            sys.stderr.flush()

    def close(self):
        if self._mode == "terminal":
            sys.stderr.write("\n")
            sys.stderr.flush()
