#!/usr/bin/env bash
# Search speed of the current tree against a base revision on the real DFG search.
#
# Usage: bench/speed_compare.sh [BASE_REV]          (default BASE_REV: 54455b4)
# Environment: GENERATIONS (default 100), THREADS (default 2), REPS (pairs, default 3),
#              JOBS (build jobs, default 2), BUILD_DIR (current tree's build, default
#              build/speed-compare; kept, so later runs rebuild incrementally).
#
# Builds the `lgp` CLI of BASE_REV in a temporary git worktree (Release) and of the working
# tree, then runs `lgp run` on examples/scenes/run_dfg.json (taken from BASE_REV, so that the
# base understands every key; outputs redirected to a temporary directory) with both binaries,
# interleaved base, new, base, new, ... with fixed generations and threads. Prints the CPU,
# each run's wall and CPU time (whole process: scene generation, search, reference scoring,
# front metrics), the search's own time and evaluations (from the front JSON's progress
# block), evaluations per second, and the medians with the ratio new/base. The two builds'
# searches diverge after the first differing error, so they do different work: compare
# evaluations per second, not wall times, for the search itself.
set -euo pipefail

BASE_REV=${1:-54455b4}
GENERATIONS=${GENERATIONS:-100}
THREADS=${THREADS:-2}
REPS=${REPS:-3}
JOBS=${JOBS:-2}
REPO=$(git -C "$(dirname "$0")" rev-parse --show-toplevel)
BUILD_DIR=${BUILD_DIR:-$REPO/build/speed-compare}

TMP=$(mktemp -d "${TMPDIR:-/tmp}/lgp-speed.XXXXXX")
cleanup() {
  git -C "$REPO" worktree remove --force "$TMP/base-src" >/dev/null 2>&1 || true
  rm -rf "$TMP"
}
trap cleanup EXIT

build() {  # build <source dir> <build dir> <log>
  cmake -S "$1" -B "$2" -DCMAKE_BUILD_TYPE=Release -DLGP_BUILD_TESTS=OFF -DLGP_BUILD_BENCH=OFF \
    -DLGP_WITH_DAEMON=OFF >"$3" 2>&1 &&
    cmake --build "$2" -j "$JOBS" --target lgp >>"$3" 2>&1 ||
    { echo "build of $1 failed; see $3" >&2; tail -20 "$3" >&2; exit 1; }
}

find_cli() {  # the lgp executable in a build tree
  local f
  for f in "$1/frontends/lgp/lgp" "$1/frontends/lgp"; do
    if [[ -f $f && -x $f ]]; then echo "$f"; return; fi
  done
  echo "no lgp executable under $1" >&2
  exit 1
}

echo "base: $BASE_REV ($(git -C "$REPO" log -1 --format='%h %s' "$BASE_REV" | cut -c1-70))"
echo "new:  working tree of $(git -C "$REPO" rev-parse --short HEAD)$(git -C "$REPO" diff --quiet HEAD || echo ' (modified)')"
echo "building base in a temporary worktree ..."
git -C "$REPO" worktree add --detach "$TMP/base-src" "$BASE_REV" >/dev/null 2>&1
build "$TMP/base-src" "$TMP/base-build" "$TMP/base-build.log"
echo "building the current tree in $BUILD_DIR ..."
build "$REPO" "$BUILD_DIR" "$TMP/new-build.log"
BASE_BIN=$(find_cli "$TMP/base-build")
NEW_BIN=$(find_cli "$BUILD_DIR")

# The config and its scene, from the base revision; outputs into the temporary directory.
RUN_DIR=$TMP/run
mkdir -p "$RUN_DIR"
cp "$TMP/base-src/examples/scenes/dfg_64.json" "$RUN_DIR/"
sed -e "s#\"front_json\": *\"[^\"]*\"#\"front_json\": \"$RUN_DIR/front.json\"#" \
  -e "s#\"front_csv\": *\"[^\"]*\"#\"front_csv\": \"$RUN_DIR/front.csv\"#" \
  "$TMP/base-src/examples/scenes/run_dfg.json" >"$RUN_DIR/run_dfg.json"
grep -q "$RUN_DIR/front.json" "$RUN_DIR/run_dfg.json" ||
  { echo "could not redirect output.front_json in run_dfg.json" >&2; exit 1; }

# The new build runs the same config with NEW_PATCH merged in (a JSON merge patch). The
# default makes the new build run the base's algorithm (one island, Nelder-Mead on 10 % of
# offspring, no Levenberg-Marquardt), so the ratio measures the engine, not a different
# search; NEW_PATCH='{}' compares the shipped defaults instead (LM passes then count as
# evaluations, and each costs more than a plain one).
NEW_PATCH=${NEW_PATCH:-'{"search": {"islands": {"count": 1}, "refine": {"offspring_share": 0.1, "lm_iterations": 0, "archive_lm_iterations": 0}}}'}
python3 - "$RUN_DIR/run_dfg.json" "$RUN_DIR/run_dfg_new.json" "$NEW_PATCH" <<'PY'
import json, sys
def merge(a, b):
    for k, v in b.items():
        if isinstance(v, dict) and isinstance(a.get(k), dict):
            merge(a[k], v)
        else:
            a[k] = v
cfg = json.load(open(sys.argv[1]))
merge(cfg, json.loads(sys.argv[3]))
json.dump(cfg, open(sys.argv[2], "w"), indent=1)
PY

json_number() {  # json_number <key> <file>: the first "key": number in the file
  grep -o "\"$1\": *[0-9.eE+-]*" "$2" | head -1 | sed 's/.*: *//'
}

echo
echo "cpu: $(grep -m1 'model name' /proc/cpuinfo | sed 's/.*: //') ($(nproc) online)"
echo "load average: $(cut -d' ' -f1-3 /proc/loadavg)"
echo "search: run_dfg.json, $GENERATIONS generations, --threads $THREADS, $REPS runs each"
echo "new build's patch: $NEW_PATCH"
echo
printf '%-4s %-5s %9s %9s %9s %12s %12s\n' run build wall_s cpu_s search_s evaluations evals/s
RESULTS=$TMP/results.txt
: >"$RESULTS"
run=0
for ((k = 0; k < REPS; ++k)); do
  for which in base new; do
    bin=$BASE_BIN
    cfg=$RUN_DIR/run_dfg.json
    if [[ $which == new ]]; then
      bin=$NEW_BIN
      cfg=$RUN_DIR/run_dfg_new.json
    fi
    rm -f "$RUN_DIR/front.json"
    run=$((run + 1))
    start=$(date +%s.%N)
    if [[ -x /usr/bin/time ]]; then
      /usr/bin/time -f '%U %S' -o "$TMP/time.txt" \
        "$bin" run "$cfg" --threads "$THREADS" --generations "$GENERATIONS" -q
      cpu=$(awk '{printf "%.2f", $1 + $2}' "$TMP/time.txt")
    else  # bash: children's user + system time
      times >"$TMP/times0.txt"  # in this shell, not a $(...) subshell
      "$bin" run "$cfg" --threads "$THREADS" --generations "$GENERATIONS" -q
      times >"$TMP/times1.txt"
      t0=$(tail -1 "$TMP/times0.txt")
      t1=$(tail -1 "$TMP/times1.txt")
      cpu=$(awk -v a="$t0" -v b="$t1" 'function s(x,  p, t) { split(x, p, " "); t = 0;
        for (i = 1; i <= 2; ++i) { split(p[i], q, "m"); t += q[1] * 60 + q[2] } return t }
        BEGIN { printf "%.2f", s(b) - s(a) }')
    fi
    end=$(date +%s.%N)
    wall=$(awk -v a="$start" -v b="$end" 'BEGIN { printf "%.2f", b - a }')
    evals=$(json_number evaluations "$RUN_DIR/front.json")
    search=$(json_number elapsed_s "$RUN_DIR/front.json")
    eps=$(awk -v e="$evals" -v s="$search" 'BEGIN { printf "%.4g", (s > 0 ? e / s : 0) }')
    printf '%-4s %-5s %9s %9s %9.3f %12s %12s\n' "$run" "$which" "$wall" "$cpu" "$search" \
      "$evals" "$eps"
    echo "$which $wall $cpu $search $evals $eps" >>"$RESULTS"
  done
done

median() {  # median <build> <column>
  awk -v w="$1" -v c="$2" '$1 == w { print $c }' "$RESULTS" | sort -g |
    awk '{ v[NR] = $1 } END { if (NR % 2) print v[(NR + 1) / 2]; else print (v[NR / 2] + v[NR / 2 + 1]) / 2 }'
}
echo
printf '%-22s %12s %12s %10s\n' median base new new/base
for col in "2 wall_s" "3 cpu_s" "4 search_s" "6 evals/s"; do
  set -- $col
  b=$(median base "$1")
  n=$(median new "$1")
  printf '%-22s %12.4g %12.4g %10.3f\n' "$2" "$b" "$n" "$(awk -v b="$b" -v n="$n" 'BEGIN { print (b > 0 ? n / b : 0) }')"
done
