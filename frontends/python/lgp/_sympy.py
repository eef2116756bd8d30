"""Formula text (core/formula.hpp's syntax) to SymPy expressions.

The syntax: statements ``name = expr`` joined by ``;``; ``+ - * /``, unary ``-``, ``^`` (a
power), ``a > b ? c : d`` (select) and calls of min, max, abs, saturate, sqrt, rsqrt, rcp,
square, exp2, log2, exp, log, pow, sin, cos, lerp and mad, and any other call by its SymPy
name (an operator whose formula spelling is a SymPy function needs no entry). Temporaries (``t0 = ...``) are
substituted into the outputs.
"""

import re

_TOKEN = re.compile(r"\s*(?:(\d+\.?\d*(?:[eE][+-]?\d+)?|\.\d+(?:[eE][+-]?\d+)?)|"
                    r"([A-Za-z_][A-Za-z0-9_]*)|(\?|:|>=|<=|>|<|[-+*/^(),]))")


def _tokens(text):
    pos, out = 0, []
    text = text.rstrip()
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if not m or m.end() == pos:
            raise ValueError(f"formula: cannot read {text[pos:pos + 12]!r}")
        if m.group(1):
            out.append(("num", m.group(1)))
        elif m.group(2):
            out.append(("name", m.group(2)))
        else:
            out.append(("op", m.group(3)))
        pos = m.end()
    out.append(("end", None))
    return out


def _functions(sp):
    return {
        "min": lambda a, b: sp.Min(a, b), "max": lambda a, b: sp.Max(a, b),
        "abs": sp.Abs, "saturate": lambda a: sp.Min(sp.Max(a, 0), 1),
        "sqrt": sp.sqrt, "rsqrt": lambda a: 1 / sp.sqrt(a), "rcp": lambda a: 1 / a,
        "square": lambda a: a**2, "exp2": lambda a: sp.Integer(2)**a,
        "log2": lambda a: sp.log(a, 2), "exp": sp.exp, "log": sp.log,
        "pow": lambda a, b: sp.Pow(a, b), "sin": sp.sin, "cos": sp.cos,
        "lerp": lambda a, b, t: a + (b - a) * t, "mad": lambda a, b, c: a * b + c,
    }


def _sympy_function(sp, name):
    """An operator whose formula spelling is SymPy's own name (atan2, tanh, ...)."""
    fn = getattr(sp, name, None)
    return fn if isinstance(fn, type) and issubclass(fn, sp.Function) else None


class _Parser:
    def __init__(self, sp, text, symbols):
        self.sp, self.toks, self.i, self.symbols = sp, _tokens(text), 0, symbols
        self.fns = _functions(sp)

    def peek(self):
        return self.toks[self.i]

    def take(self, value=None):
        tok = self.toks[self.i]
        if value is not None and tok[1] != value:
            raise ValueError(f"formula: expected {value!r}, found {tok[1]!r}")
        self.i += 1
        return tok

    def parse(self):
        e = self.ternary()
        if self.peek()[0] != "end":
            raise ValueError(f"formula: unexpected {self.peek()[1]!r}")
        return e

    def ternary(self):
        cond = self.additive()
        tok = self.peek()
        if tok == ("op", ">") or tok == ("op", ">=") or tok == ("op", "<") or tok == ("op", "<="):
            self.take()
            rhs = self.additive()
            rel = {">": self.sp.Gt, ">=": self.sp.Ge, "<": self.sp.Lt, "<=": self.sp.Le}[tok[1]]
            self.take("?")
            a = self.ternary()
            self.take(":")
            b = self.ternary()
            return self.sp.Piecewise((a, rel(cond, rhs)), (b, True))
        return cond

    def additive(self):
        e = self.term()
        while self.peek() in (("op", "+"), ("op", "-")):
            op = self.take()[1]
            r = self.term()
            e = e + r if op == "+" else e - r
        return e

    def term(self):
        e = self.unary()
        while self.peek() in (("op", "*"), ("op", "/")):
            op = self.take()[1]
            r = self.unary()
            e = e * r if op == "*" else e / r
        return e

    def unary(self):
        if self.peek() == ("op", "-"):
            self.take()
            return -self.unary()
        if self.peek() == ("op", "+"):
            self.take()
            return self.unary()
        return self.power()

    def power(self):
        base = self.atom()
        if self.peek() == ("op", "^"):
            self.take()
            return base**self.unary()
        return base

    def atom(self):
        kind, v = self.take()
        if kind == "num":
            return self.sp.Float(v) if any(c in v for c in ".eE") else self.sp.Integer(v)
        if kind == "name":
            if self.peek() == ("op", "("):
                fn = self.fns.get(v) or _sympy_function(self.sp, v)
                if fn is None:
                    raise ValueError(f"formula: unknown function {v!r}")
                self.take("(")
                args = [self.ternary()]
                while self.peek() == ("op", ","):
                    self.take()
                    args.append(self.ternary())
                self.take(")")
                return fn(*args)
            if v not in self.symbols:
                raise ValueError(f"formula: unknown name {v!r}")
            return self.symbols[v]
        if (kind, v) == ("op", "("):
            e = self.ternary()
            self.take(")")
            return e
        raise ValueError(f"formula: unexpected {v!r}")


def formula_to_sympy(text, inputs, outputs):
    """Per output name, the SymPy expression of a formula over Symbols named like the inputs."""
    import sympy as sp

    symbols = {n: sp.Symbol(n, real=True) for n in inputs}
    out = {}
    for stmt in text.split(";"):
        if not stmt.strip():
            continue
        name, sep, expr = stmt.partition("=")
        name = name.strip()
        if not sep or not name:
            raise ValueError(f"formula: not a statement: {stmt.strip()!r}")
        value = _Parser(sp, expr, symbols).parse()
        if name in outputs:
            out[name] = value
        else:
            symbols[name] = value  # a temporary: substituted where it is read
    return out
