#!/usr/bin/env bash
# One entry point for a fresh machine:
#   scripts/lgp.sh run    install the packages the CLI needs (RUN_PACKAGES) where missing,
#                         build the `lgp` CLI (Release) and only it, run the example search
#   scripts/lgp.sh test   install every package (RUN_PACKAGES and TEST_PACKAGES), build
#                         everything (Release; every optional part, whatever the build tree
#                         cached), run the whole test suite, in which no GPU, MPI, Python or
#                         daemon test may skip (LGP_TEST_NO_SKIP=1)
#   scripts/lgp.sh deps   only install every package
#   scripts/lgp.sh build [TARGET...]  install every package + build the targets (default: all)
#   scripts/lgp.sh install [PREFIX]   build lgp, lgpd and the libraries, and install them,
#                         their headers and the CMake package under PREFIX (default ~/.local)
# Environment: BUILD_DIR (default build/release), JOBS (default nproc).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# Absolute, so that a relative BUILD_DIR means the same folder in every step.
BUILD_DIR="$(realpath -m "${BUILD_DIR:-$ROOT/build/release}")"
JOBS="${JOBS:-$(nproc)}"

# Debian packages. Nothing is downloaded at build time and nothing is vendored.
# What `run` needs: the compiler and every find_package(... REQUIRED) of the top-level
# CMakeLists.txt outside the tests and benchmarks (Eigen3, nlohmann_json, spdlog, cxxopts;
# OpenMP and Threads come with the compiler).
RUN_PACKAGES=(
  build-essential cmake ninja-build
  libeigen3-dev nlohmann-json3-dev libspdlog-dev libcxxopts-dev
)
# lgpd (without them CMake skips the daemon): SQLite, libmicrohttpd (its server), cpp-httplib
# (the HTTP client of `lgp` and the tests) and pkg-config to find them.
DAEMON_PACKAGES=(pkg-config libcpp-httplib-dev libmicrohttpd-dev libsqlite3-dev)
# The Python module (frontends/python) and what its tests use (scikit-learn's estimator
# checks, SymPy for Member.sympy).
PYTHON_PACKAGES=(python3-dev pybind11-dev python3-numpy)
PYTHON_TEST_PACKAGES=(python3-pytest python3-sklearn python3-sympy)
# The rest, for `test`: the test and benchmark libraries (LGP_BUILD_TESTS, LGP_BUILD_BENCH),
# MPI (LGP_WITH_MPI), the GPU backend (LGP_WITH_GPU) and Chromium for the browser test.
TEST_PACKAGES=(
  "${DAEMON_PACKAGES[@]}"
  "${PYTHON_PACKAGES[@]}" "${PYTHON_TEST_PACKAGES[@]}"
  libgtest-dev libgmock-dev libbenchmark-dev
  openmpi-bin libopenmpi-dev
  glslang-tools glslang-dev libvulkan-dev mesa-vulkan-drivers
  chromium
)
# The find_package names TEST_PACKAGES provide: a `run` build must configure without them
# (tests/repo/run_packages_test.sh checks it).
TEST_FIND_PACKAGES=(GTest benchmark MPI Vulkan glslang SQLite3 httplib PkgConfig pybind11)
# The cache options of a `run` build: no tests or benchmarks, so GTest and benchmark are not
# required, and no optional part is required either.
RUN_CMAKE_ARGS=(-DLGP_BUILD_TESTS=OFF -DLGP_BUILD_BENCH=OFF -DLGP_REQUIRE_ALL=OFF)
# The cache options of a `test` build: every part, whatever an earlier configure cached (a `run`
# before the packages were there caches LGP_WITH_GPU=OFF and LGP_WITH_MPI=OFF), and a part
# that cannot be built stops the configure (LGP_REQUIRE_ALL) instead of dropping its tests.
# Warnings are errors here (LGP_WERROR): a switch that misses an operator, a metric or a
# language, or a Status nobody reads, stops the build (CONTRIBUTING.md).
TEST_CMAKE_ARGS=(-DLGP_BUILD_TESTS=ON -DLGP_BUILD_BENCH=ON -DLGP_WITH_GPU=ON -DLGP_WITH_MPI=ON
  -DLGP_WITH_PYTHON=ON -DLGP_WITH_DAEMON=ON -DLGP_WITH_EMIT=ON -DLGP_WITH_DATASETS=ON
  -DLGP_REQUIRE_ALL=ON -DLGP_WERROR=ON)

# Installs the given packages where missing.
deps() {
  local missing=()
  for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if ((${#missing[@]} == 0)); then
    echo "lgp: all $# packages present"
    return
  fi
  echo "lgp: installing ${missing[*]}"
  local sudo=""
  if [[ $(id -u) -ne 0 ]]; then sudo="sudo"; fi
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends \
    "${missing[@]}" >/dev/null
}

# Configures the project with the cache options in CMAKE_ARGS (default: tests and benchmarks
# on). `run` and `test` share the build tree: the libraries and binaries do not depend on
# those options, so switching does not rebuild them.
CMAKE_ARGS=(-DLGP_BUILD_TESTS=ON -DLGP_BUILD_BENCH=ON)
configure() {
  # Ninja schedules every compile of the project in one graph; make waits at each library's
  # end with one core idle. An existing build tree keeps the generator it was made with.
  local gen=()
  if [[ ! -f "$BUILD_DIR/CMakeCache.txt" ]] && command -v ninja >/dev/null; then gen=(-G Ninja); fi
  # The Python module is for Debian's python3, the one the packages above install numpy for
  # (another python3 first on PATH, e.g. pyenv's, may lack it), also in a tree configured
  # before by other means.
  local py=()
  if [[ -x /usr/bin/python3 ]]; then py=(-DPython3_EXECUTABLE=/usr/bin/python3); fi
  # A package searched for before it was installed is cached as NOTFOUND; those entries are
  # dropped so that each search runs again (the others keep the tree's choices).
  local stale=()
  if [[ -f "$BUILD_DIR/CMakeCache.txt" ]]; then
    while IFS= read -r name; do stale+=(-U "$name"); done < <(
      sed -n 's/^\([A-Za-z0-9_.+-]*\):[A-Z]*=.*-NOTFOUND$/\1/p' "$BUILD_DIR/CMakeCache.txt")
  fi
  cmake -S "$ROOT" -B "$BUILD_DIR" "${gen[@]}" "${stale[@]}" -DCMAKE_BUILD_TYPE=Release \
    "${CMAKE_ARGS[@]}" "${py[@]}" >/dev/null
}

# configure, then build the given targets, or everything.
build() {
  configure
  if (($# > 0)); then
    cmake --build "$BUILD_DIR" -j "$JOBS" --target "$@"
  else
    cmake --build "$BUILD_DIR" -j "$JOBS"
  fi
}

# Sourced (by the tests), it only defines the lists above.
if [[ "${BASH_SOURCE[0]}" != "$0" ]]; then return 0; fi

cmd="${1:-}"
case "$cmd" in
  deps) deps "${RUN_PACKAGES[@]}" "${TEST_PACKAGES[@]}" ;;
  build)
    shift
    deps "${RUN_PACKAGES[@]}" "${TEST_PACKAGES[@]}"
    build "$@"
    ;;
  run)
    # The example needs the CLI only; tests and benchmarks are built by `test`.
    deps "${RUN_PACKAGES[@]}"
    CMAKE_ARGS=("${RUN_CMAKE_ARGS[@]}")
    build lgp
    # The config's output paths are relative to it: the front lands in examples/.
    "$BUILD_DIR/frontends/lgp" run "$ROOT/examples/quickstart.json"
    "$BUILD_DIR/frontends/lgp" front "$ROOT/examples/quickstart-front.json"
    ;;
  install)
    prefix="$(realpath -m "${2:-$HOME/.local}")"
    deps "${RUN_PACKAGES[@]}" "${DAEMON_PACKAGES[@]}" "${PYTHON_PACKAGES[@]}"
    CMAKE_ARGS=("${RUN_CMAKE_ARGS[@]}")
    build lgp_installables
    cmake --install "$BUILD_DIR" --prefix "$prefix"
    echo "lgp: installed lgp and lgpd in $prefix/bin; put it on PATH with"
    echo "  export PATH=\"$prefix/bin:\$PATH\""
    pydir=$(find "$prefix/lib" -maxdepth 3 -type d -path '*/site-packages/lgp' 2>/dev/null | head -1)
    if [[ -n "$pydir" ]]; then
      echo "lgp: installed the Python package in $pydir; where your Python does not look there:"
      echo "  export PYTHONPATH=\"$(dirname "$pydir"):\$PYTHONPATH\""
    fi
    ;;
  test)
    deps "${RUN_PACKAGES[@]}" "${TEST_PACKAGES[@]}"
    CMAKE_ARGS=("${TEST_CMAKE_ARGS[@]}")
    build
    # Every package the tests need is installed now: a GPU, MPI, Python or daemon test that
    # would skip fails instead (tests/skip.hpp, tests/python/conftest.py).
    LGP_TEST_NO_SKIP=1 ctest --test-dir "$BUILD_DIR" --output-on-failure -j "$JOBS" --timeout 600 \
      --no-tests=error
    ;;
  *)
    echo "usage: scripts/lgp.sh run|test|deps|build|install [PREFIX]" >&2
    exit 2
    ;;
esac
