#!/usr/bin/env bash
# The fuzz driver at N times its CI case count (default 20), under ASan+UBSan: builds the
# debug-asan preset's fuzz_test and lgpd, then runs every fuzz case. A nightly job, not CI.
#   scripts/fuzz-nightly.sh [SCALE]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
SCALE="${1:-20}"
cd "$ROOT"
cmake --preset debug-asan >/dev/null
cmake --build build/debug-asan -j "$(nproc)" --target fuzz_test lgpd lgp
LGP_FUZZ_SCALE="$SCALE" ASAN_OPTIONS=detect_leaks=0:abort_on_error=1 \
  UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  build/debug-asan/tests/fuzz/fuzz_test
