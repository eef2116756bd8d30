#!/usr/bin/env bash
# `scripts/lgp.sh run` installs RUN_PACKAGES only: the project must configure, with the cache
# options `run` uses, when every find_package that TEST_PACKAGES provide finds nothing (CMake's
# CMAKE_DISABLE_FIND_PACKAGE_<name>), and still define the `lgp` target `run` builds.
#
# Usage: run_packages_test.sh SOURCE_DIR CMAKE
set -uo pipefail
src="$1" cmake="$2"
# shellcheck source=../../scripts/lgp.sh
source "$src/scripts/lgp.sh"
work="$(mktemp -d "${TMPDIR:-/tmp}/lgp-runpkgs.XXXXXX")"
trap 'rm -rf "$work"' EXIT

args=("${RUN_CMAKE_ARGS[@]}")
for p in "${TEST_FIND_PACKAGES[@]}"; do args+=("-DCMAKE_DISABLE_FIND_PACKAGE_$p=ON"); done
gen=()
if command -v ninja >/dev/null; then gen=(-G Ninja); fi
if ! "$cmake" -S "$src" -B "$work" "${gen[@]}" -DCMAKE_BUILD_TYPE=Release "${args[@]}" \
  >"$work.log" 2>&1; then
  cat "$work.log"
  echo "run_packages_test: the project does not configure without ${TEST_FIND_PACKAGES[*]}:" \
    "a find_package(... REQUIRED) needs a package that RUN_PACKAGES lacks" >&2
  rm -f "$work.log"
  exit 1
fi
rm -f "$work.log"
if ! "$cmake" --build "$work" --target help | grep -qE '(^|[ /])lgp(:| )'; then
  echo "run_packages_test: no lgp target in a build configured as \`run\` does" >&2
  exit 1
fi
echo "run_packages_test: configures with ${RUN_CMAKE_ARGS[*]} and none of ${TEST_FIND_PACKAGES[*]}"
