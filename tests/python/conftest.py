"""Shared fixtures of the Python tests (run by CTest with PYTHONPATH at the built package and
LGP_CLI / LGPD naming the binaries of the same build)."""

import os

import numpy as np
import pytest

EXAMPLES = os.path.join(os.path.dirname(__file__), "..", "..", "examples")


def target(X):
    """The recovery target of the issue: exp2(-7x - 4y^2)."""
    return np.exp2(-7 * X[:, 0] - 4 * X[:, 1] ** 2)


def _skip_is_failure(report):
    """Under `scripts/lgp.sh test` (LGP_TEST_NO_SKIP=1), which installs everything these tests
    use (lgpd, scikit-learn, SymPy) and builds every part, a skip is a broken build: it is
    reported as a failure, with the skip's reason."""
    if report.skipped and os.environ.get("LGP_TEST_NO_SKIP", "0") not in ("", "0"):
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else report.longrepr
        report.outcome = "failed"
        report.longrepr = ("LGP_TEST_NO_SKIP is set (scripts/lgp.sh test): this test may not "
                           f"skip, and would have: {reason}")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    _skip_is_failure(outcome.get_result())


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector):
    # A module that skips as a whole (pytest.importorskip at its top).
    outcome = yield
    _skip_is_failure(outcome.get_result())


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
