#!/usr/bin/env bash
# Installs the build into a temporary prefix, then configures, builds and runs a C++ program
# that finds it with find_package(lgp) (consumer/): the installed headers, libraries and
# package files are enough, with nothing from the source or build tree.
#
# Usage: install_test.sh CMAKE BUILD_DIR CONSUMER_SOURCE_DIR CXX_COMPILER
set -euo pipefail
cmake="$1" build="$2" consumer="$3" cxx="$4"
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
