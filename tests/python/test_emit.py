"""Member.emit against `lgp emit`, byte for byte."""

import subprocess

import pytest

import lgp

OPS = ["add", "sub", "mul", "div", "mad", "exp2", "sqrt", "min", "max"]


@pytest.fixture(scope="module")
def saved_front(tmp_path_factory):
    import numpy as np

    g = np.linspace(0.05, 1, 16)
    X = np.array([(a, b) for b in g for a in g])
    y = np.exp2(-7 * X[:, 0] - 4 * X[:, 1] ** 2) / (0.5 + X[:, 1])
    front = lgp.fit(X, y, inputs=["mu", "r"], outputs=["B"], ops=OPS, generations=40,
                    threads=1, seed=5)
    path = tmp_path_factory.mktemp("emit") / "front.json"
    front.save(path)
    return lgp.load_front(path), str(path)


LANG_CASES = [
    ("hlsl", {}, []),
    ("glsl", {}, []),
    ("cpp", {}, []),
    ("hlsl", {"fast": True}, ["--fast"]),
    ("glsl", {"precision": "half", "name": "dfg_b"}, ["--precision", "half", "--name", "dfg_b"]),
    ("cpp", {"precision": "double", "helpers": False}, ["--precision", "double", "--no-helpers"]),
    ("cpp", {"exact_math": True, "header": False}, ["--exact-math", "--no-header"]),
    ("hlsl", {"measure": False, "pow_rewrites": False, "domain_rewrites": False},
     ["--no-measure", "--no-pow-rewrites", "--no-domain-rewrites"]),
]


@pytest.mark.parametrize("lang, kwargs, flags", LANG_CASES)
def test_emit_is_lgp_emit(saved_front, cli, lang, kwargs, flags):
    front, path = saved_front
    for m in (front[len(front) // 2], front[len(front) - 1]):
        want = subprocess.run([cli, "emit", path, "--member", str(m.index), "--lang", lang,
                               *flags], capture_output=True, check=True).stdout.decode()
        assert m.emit(lang, **kwargs) == want


def test_emit_bad_arguments(saved_front):
    front, _ = saved_front
    with pytest.raises(ValueError, match="lang"):
        front[0].emit("metal")
    with pytest.raises(ValueError, match="precision"):
        front[0].emit("hlsl", precision="quad")
    with pytest.raises(ValueError, match="function_name|name"):
        front[0].emit("cpp", name="3x")


def test_every_language_is_tested_here():
    # The list above is by hand (each language with its options): it covers lgp.languages.
    assert set(lgp.languages) <= {lang for lang, _kwargs, _flags in LANG_CASES}


def test_every_operator_has_a_sympy_translation():
    # Registry coverage: the formula lgp prints for every operator reads into SymPy (Member.sympy)
    # and computes the operator's value.
    sympy = pytest.importorskip("sympy")
    from lgp import _lgp
    from lgp._sympy import formula_to_sympy

    ops = _lgp.operators()
    assert {o["name"] for o in ops} >= set(OPS)
    for o in ops:
        expr = formula_to_sympy(o["formula"], ["x", "y", "z", "w"], ["v"])["v"]
        x, y, z, w = (sympy.Symbol(n, real=True) for n in "xyzw")
        got = float(expr.subs(dict(zip((x, y, z, w), o["point"]))).evalf())
        assert got == pytest.approx(o["value"], rel=1e-9, abs=1e-12), (o["name"], o["formula"])
