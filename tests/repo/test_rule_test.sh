#!/usr/bin/env bash
# The rule of `scripts/lgp.sh test` (README, "The rule of `test`"):
#  1. its configure turns every part back on whatever the build tree cached (a `run` before
#     the packages were installed caches LGP_WITH_GPU=OFF and LGP_WITH_MPI=OFF), and under
#     LGP_REQUIRE_ALL a part that cannot be built stops the configure;
#  2. under LGP_TEST_NO_SKIP=1 a GPU test that would skip fails, naming why (tests/skip.hpp),
#     and so does a Python test (tests/python/conftest.py); without it they skip.
#
# Usage: test_rule_test.sh SOURCE_DIR CMAKE SKIPPING_GTEST [PYTHON]
#   SKIPPING_GTEST: a GPU test binary (it skips when its Vulkan driver is missing)
#   PYTHON: the interpreter of the Python tests (that part is left out without it)
set -uo pipefail
src="$1" cmake="$2" gtest="$3" python="${4:-}"
# shellcheck source=../../scripts/lgp.sh
source "$src/scripts/lgp.sh"
work="$(mktemp -d "${TMPDIR:-/tmp}/lgp-testrule.XXXXXX")"
trap 'rm -rf "$work"' EXIT
fail() {
  echo "test_rule_test: $*" >&2
  exit 1
}
cached() { sed -n "s/^$1:[A-Z]*=//p" "$BUILD_DIR/CMakeCache.txt"; }

# 1. A tree as `run` leaves it on a machine without the GPU and MPI packages.
BUILD_DIR="$work/build"
CMAKE_ARGS=("${RUN_CMAKE_ARGS[@]}" -DLGP_WITH_GPU=OFF -DLGP_WITH_MPI=OFF)
configure >"$work/run.log" 2>&1 || {
  cat "$work/run.log"
  fail "the run-style configure failed"
}
[[ "$(cached LGP_WITH_GPU)" == OFF && "$(cached LGP_WITH_MPI)" == OFF ]] ||
  fail "the setup did not cache LGP_WITH_GPU/LGP_WITH_MPI=OFF"
CMAKE_ARGS=("${TEST_CMAKE_ARGS[@]}")
configure >"$work/test.log" 2>&1 || {
  cat "$work/test.log"
  fail "test's configure failed on this machine"
}
for v in LGP_WITH_GPU LGP_WITH_MPI LGP_WITH_PYTHON LGP_WITH_DAEMON LGP_REQUIRE_ALL LGP_BUILD_TESTS; do
  [[ "$(cached "$v")" == ON ]] || fail "after test's configure $v is '$(cached "$v")', not ON"
done
# A part that cannot be built (here: pybind11 hidden from CMake) stops test's configure.
if "$cmake" -S "$src" -B "$BUILD_DIR" -DCMAKE_DISABLE_FIND_PACKAGE_pybind11=ON \
  >"$work/missing.log" 2>&1; then
  fail "with LGP_REQUIRE_ALL on, a configure without pybind11 succeeded"
fi
grep -q "Python module not built" "$work/missing.log" || {
  cat "$work/missing.log"
  fail "the failed configure does not say which part is missing"
}
echo "test_rule_test: test's configure turns GPU, MPI, Python and lgpd on over a run's cache"

# 2. A skip is a failure under LGP_TEST_NO_SKIP, and only there.
# The GPU test binary with no driver to find: its tests that need one skip.
no_driver=(LGP_LAVAPIPE_ICD=/nonexistent/lvp_icd.json LGP_RADV_ICD=/nonexistent/radeon_icd.json)
out="$(env LGP_TEST_NO_SKIP=0 "${no_driver[@]}" "$gtest" 2>&1)" ||
  fail "$gtest failed without LGP_TEST_NO_SKIP: $out"
grep -q "SKIPPED" <<<"$out" || fail "$gtest did not skip without its driver: $out"
if out="$(env LGP_TEST_NO_SKIP=1 "${no_driver[@]}" "$gtest" 2>&1)"; then
  fail "$gtest passed under LGP_TEST_NO_SKIP=1 without its driver: $out"
fi
grep -q "may not skip, and would have:" <<<"$out" && grep -q "no Vulkan driver to run shaders" <<<"$out" ||
  fail "no reason given: $out"
if [[ -n "$python" ]]; then
  mkdir -p "$work/py"
  printf 'import pytest\n\ndef test_skips():\n    pytest.skip("a missing package")\n' \
    >"$work/py/test_skip.py"
  # The conftest of tests/python, as a plugin, on a test that skips.
  run_pytest() {
    PYTHONPATH="$src/tests/python" "$python" -m pytest -q -p no:cacheprovider -p conftest \
      --rootdir="$work/py" "$work/py/test_skip.py" 2>&1
  }
  out="$(LGP_TEST_NO_SKIP=0 run_pytest)" ||
    fail "a skipping Python test failed without LGP_TEST_NO_SKIP: $out"
  if out="$(LGP_TEST_NO_SKIP=1 run_pytest)"; then
    fail "a skipping Python test passed under LGP_TEST_NO_SKIP=1: $out"
  fi
  grep -q "would have: .*a missing package" <<<"$out" || fail "no reason given: $out"
fi
echo "test_rule_test: under LGP_TEST_NO_SKIP=1 a skip is a failure with its reason"
