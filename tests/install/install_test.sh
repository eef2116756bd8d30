#!/usr/bin/env bash
# Installs the build into a temporary prefix, then configures, builds and runs a C++ program
# that finds it with find_package(lgp) (consumer/): the installed headers, libraries and
# package files are enough, with nothing from the source or build tree.
#
# Where the Python module is built, the installed package is imported from the prefix alone and
# runs a fit.
#
# Usage: install_test.sh CMAKE BUILD_DIR CONSUMER_SOURCE_DIR CXX_COMPILER [PYTHON]
set -euo pipefail
cmake="$1" build="$2" consumer="$3" cxx="$4" python="${5:-}"
work="$(mktemp -d "${TMPDIR:-/tmp}/lgp-install.XXXXXX")"
trap 'rm -rf "$work"' EXIT

"$cmake" --install "$build" --prefix "$work/prefix" >"$work/install.log"
for f in bin/lgp include/lgp/search/search.hpp lib/cmake/lgp/lgpConfig.cmake \
  lib/cmake/lgp/lgpConfigVersion.cmake lib/cmake/lgp/lgpTargets.cmake; do
  [[ -e "$work/prefix/$f" ]] || { echo "install_test: $f not installed" >&2; exit 1; }
done
"$work/prefix/bin/lgp" --help >/dev/null

# A copy of the consumer, so that nothing resolves against the source tree.
cp -r "$consumer" "$work/consumer"
"$cmake" -S "$work/consumer" -B "$work/build" -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_CXX_COMPILER="$cxx" -DCMAKE_PREFIX_PATH="$work/prefix"
"$cmake" --build "$work/build" -j 2
"$work/build/consumer"

if [[ -n "$python" ]]; then
  pydir="$(find "$work/prefix/lib" -maxdepth 3 -type d -path '*/site-packages/lgp' | head -1)"
  [[ -n "$pydir" ]] || { echo "install_test: the Python package was not installed" >&2; exit 1; }
  # LGP_PYTHON_PRELOAD: the sanitizer runtimes in a sanitizer build (tests/install/CMakeLists.txt).
  preload=()
  if [[ -n "${LGP_PYTHON_PRELOAD:-}" ]]; then preload=("LD_PRELOAD=$LGP_PYTHON_PRELOAD"); fi
  (cd "$work" && env "${preload[@]}" PYTHONPATH="$(dirname "$pydir")" "$python" -c '
import numpy as np, lgp
assert lgp.__file__.startswith("'"$work"'/prefix/"), lgp.__file__
x = np.linspace(0, 1, 64).reshape(-1, 1)
front = lgp.fit(x, 3 * x[:, 0] + 1, generations=20, threads=1)
print("install_test: python", front.best().formula)
assert front.best().error < 1e-5')
fi
