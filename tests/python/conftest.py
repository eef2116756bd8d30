"""Shared fixtures of the Python tests (run by CTest with PYTHONPATH at the built package and
LGP_CLI / LGPD naming the binaries of the same build)."""

import os

import numpy as np
import pytest

EXAMPLES = os.path.join(os.path.dirname(__file__), "..", "..", "examples")


def target(X):
    """The recovery target of the issue: exp2(-7x - 4y^2)."""
    return np.exp2(-7 * X[:, 0] - 4 * X[:, 1] ** 2)


@pytest.fixture
def grid():
    """A 20 x 20 grid on [0, 1]^2 and the target on it."""
    g = np.linspace(0, 1, 20)
    X = np.array([(a, b) for b in g for a in g])
    return X, target(X)


@pytest.fixture
def cli():
    path = os.environ.get("LGP_CLI")
    if not path:
        pytest.skip("LGP_CLI is not set (CTest sets it to the built lgp)")
    return path


@pytest.fixture
def examples():
    return os.path.abspath(EXAMPLES)
