#!/usr/bin/env bash
# Before you stop: the test suite built with AddressSanitizer and UBSan (the debug-asan preset,
# in build/debug-asan), every test or those matching a CTest regex. A sanitizer report ends
# the process that made it (ASan aborts, UBSan halts), so the test fails and its output shows
# the report. Leaks are not checked (the Vulkan drivers, Open MPI and Python keep memory to
# the end). The Python tests load the instrumented module through the sanitizer runtimes
# (tests/python/CMakeLists.txt preloads them).
#   scripts/sanitize.sh [CTEST_REGEX]
# Environment: JOBS (default nproc); CMAKE_CXX_COMPILER_LAUNCHER (e.g. ccache) is honoured.
# A debug build of everything takes a while; the suite runs several times slower than Release.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
JOBS="${JOBS:-$(nproc)}"
cd "$ROOT"
gen=()
if [[ ! -f build/debug-asan/CMakeCache.txt ]] && command -v ninja >/dev/null; then gen=(-G Ninja); fi
# Debian's python3, the one the packages install numpy for (as scripts/lgp.sh does).
py=()
if [[ -x /usr/bin/python3 ]]; then py=(-DPython3_EXECUTABLE=/usr/bin/python3); fi
cmake --preset debug-asan "${gen[@]}" "${py[@]}" >/dev/null
cmake --build build/debug-asan -j "$JOBS"
export ASAN_OPTIONS="detect_leaks=0:abort_on_error=1:check_initialization_order=1:detect_stack_use_after_return=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
# The daemon tests' deadlines (tests/daemon/daemon_harness.hpp) are hang guards sized for
# Release; a search here runs about 100x slower (ASan and UBSan at -O1: the crash tests'
# 6,000-generation runs take 20-30 minutes each on 2 cores, 10-20 s in Release).
export LGP_TEST_TIME_SCALE=30
args=()
if (($# > 0)); then args=(-R "$1"); fi
ctest --test-dir build/debug-asan --output-on-failure -j "$JOBS" --timeout 7200 "${args[@]}"
