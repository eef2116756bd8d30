#!/bin/bash
# lgp_gpu_time (bench/gpu_time) end to end on lavapipe, the CPU Vulkan driver: every member and
# reference of a committed front is emitted, compiled and dispatched, each writes only finite
# values, each formula kernel's sums equal the host's recomputation of the formula (the tool's
# own check, which exits 4 otherwise), the identical I/O-only kernels are shared, and the
# report and results agree. Bad
# input gets a message naming the option, and a GPU-only run on a machine with no GPU says
# which devices there are. Timings on a CPU driver mean nothing and are not checked.
# Usage: gpu_time_test.sh <lgp_gpu_time> <repo root>
# Exit 77 (skipped) where lavapipe is not installed, a failure under LGP_TEST_NO_SKIP.
set -u
GT=$1
ROOT=$2
W=$(mktemp -d)
trap 'rm -rf "$W"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
ICD=${LGP_LAVAPIPE_ICD:-}
if [ -z "$ICD" ]; then
  for d in /usr/share/vulkan/icd.d /etc/vulkan/icd.d; do
    for f in "$d"/lvp_icd."$(uname -m)".json "$d"/lvp_icd.json; do
      [ -f "$f" ] && ICD=$f && break 2
    done
  done
fi
if [ -z "$ICD" ]; then
  [ -n "${LGP_TEST_NO_SKIP:-}" ] && [ "${LGP_TEST_NO_SKIP}" != 0 ] &&
    fail "LGP_TEST_NO_SKIP is set and lavapipe's ICD (mesa-vulkan-drivers) is not installed"
  echo "skipped: lavapipe's ICD not found (mesa-vulkan-drivers)"
  exit 77
fi
export VK_ICD_FILENAMES=$ICD VK_DRIVER_FILES=$ICD VK_LOADER_LAYERS_DISABLE='~all~'
FRONT=$ROOT/bench/results/quality/normalization_front.json
SMALL=(--invocations 256 --iters 16 --rounds 2 --warmup 1 --check 4)

"$GT" --front "$FRONT" --out "$W/a" --allow-cpu "${SMALL[@]}" >"$W/out.txt" 2>&1 ||
  fail "run on lavapipe: $(cat "$W/out.txt")"
python3 - "$FRONT" "$W/a" <<'PY' || fail "results.json does not match the front"
import json, math, sys
front = json.load(open(sys.argv[1]))
res = json.load(open(sys.argv[2] + "/results.json"))
md = open(sys.argv[2] + "/report.md").read()
assert res["device"]["type"] == "cpu", res["device"]
(f,) = res["fronts"]
rows = f["formulas"]
members = [r for r in rows if not r["reference"]]
refs = [r for r in rows if r["reference"]]
assert len(members) == len(front["members"]), (len(members), len(front["members"]))
assert [r["label"] for r in refs] == [r["name"] for r in front["references"]]
assert all(r["finite"] for r in rows), [r["label"] for r in rows if not r["finite"]]
assert res["checked_invocations"] == 4 and res["check_failures"] == 0, res["check_failures"]
assert all(r["check_ok"] and r["check_deviation"] < 1e-4 for r in rows), \
    [(r["label"], r["check_deviation"]) for r in rows if not r["check_ok"]]
for r, m in zip(members, front["members"]):
    assert r["rdna2_instructions"] == m["cost_measured"]["rdna2"]["instructions"], r["label"]
    assert r["error"] == m["error"], r["label"]
    assert len(r["formula_ns"]) == 2 and len(r["baseline_ns"]) == 2, r["label"]
    assert all(t > 0 for t in r["formula_ns"] + r["baseline_ns"]), r["label"]
# Members reading the same inputs share one I/O-only kernel.
assert res["kernels"] < 2 * len(rows), (res["kernels"], len(rows))
c = f["correlation"]
assert c["members"] == len(members)
assert all(math.isfinite(c[k]) for k in c if k != "driver_statistics"), c
assert "| `" in md and "## Every formula of" in md and "all agree" in md
assert md.count("\n| m") == len(members), md.count("\n| m")
PY

# --stats-only on RADV's null device (compiles for an AMD GPU, runs nothing): the driver's own
# statistics of every kernel, formula minus baseline; ACO's instruction count of the timing
# kernel ranks the formulas as the front's measured RDNA2 count does.
RADV=""
for d in /usr/share/vulkan/icd.d /etc/vulkan/icd.d; do
  for f in "$d"/radeon_icd."$(uname -m)".json "$d"/radeon_icd.json; do
    [ -f "$f" ] && RADV=$f && break 2
  done
done
[ -n "$RADV" ] || fail "RADV's ICD (mesa-vulkan-drivers) is not installed beside lavapipe's"
VK_ICD_FILENAMES=$RADV VK_DRIVER_FILES=$RADV RADV_FORCE_FAMILY=navi21 \
  "$GT" --front "$FRONT" --out "$W/s" --stats-only >"$W/out.txt" 2>&1 ||
  fail "--stats-only on RADV's null device: $(cat "$W/out.txt")"
python3 - "$W/s" <<'PY' || fail "--stats-only results"
import json, sys
res = json.load(open(sys.argv[1] + "/results.json"))
assert res["stats_only"] and res["device"]["pipeline_statistics"], res["device"]
rows = [r for r in res["fronts"][0]["formulas"] if not r["reference"]]
assert all("Instructions" in r["driver_stats"] and r["ps_per_eval"] is None for r in rows)
assert not any("ash" in k for r in rows for k in r["driver_stats"])
c = res["pooled"]["driver_statistics"]["Instructions"]
assert c["members"] == len(rows) and c["spearman_rdna2"] > 0.8, c
assert "Statistics only" in open(sys.argv[1] + "/report.md").read()
PY

# A reference named with a '|' and a line break stays one table cell.
python3 - "$FRONT" "$W/odd.json" <<'PY'
import json, sys
f = json.load(open(sys.argv[1]))
f["references"][0]["name"] = "odd | name\nnext"
json.dump(f, open(sys.argv[2], "w"))
PY
VK_ICD_FILENAMES=$RADV VK_DRIVER_FILES=$RADV RADV_FORCE_FAMILY=navi21 \
  "$GT" --front "$W/odd.json" --out "$W/o" --stats-only >"$W/out.txt" 2>&1 ||
  fail "--stats-only, odd reference name: $(cat "$W/out.txt")"
python3 - "$W/o/report.md" <<'PY' || fail "a reference's name breaks the report's table"
import re, sys
md = open(sys.argv[1]).read()
assert "| odd \\| name next |" in md, md[-2000:]
rows = md.split("## Every formula of")[1].splitlines()[2:]
rows = [r for r in rows if r.startswith("|")]
assert rows and all(len(re.findall(r"(?<!\\)\|", r)) == 8 for r in rows), rows[:3]
PY

# Bad input: a message naming the option, exit 1, never a crash.
expect_error() {  # <pattern> <args...>
  local pat=$1
  shift
  "$GT" "$@" >"$W/e.txt" 2>&1
  local rc=$?
  [ "$rc" = 1 ] || fail "$* exited $rc, expected 1: $(cat "$W/e.txt")"
  grep -q -- "$pat" "$W/e.txt" || fail "$*: no '$pat' in: $(cat "$W/e.txt")"
}
expect_error "--front: required" --out "$W/x"
expect_error "--front: cannot read" --front "$W/none.json" --out "$W/x"
echo '{"format": "lgp-front/1"}' >"$W/bad.json"
expect_error "no members array" --front "$W/bad.json" --out "$W/x"
expect_error "--lang: expected a shader language (hlsl or glsl)" --front "$FRONT" --out "$W/x" --lang cpp
expect_error "--invocations: must be a positive multiple of 128" --front "$FRONT" --out "$W/x" \
  --invocations 100
# Only a CPU device and no --allow-cpu: the devices there are, by name.
expect_error "no Vulkan device matches.*llvmpipe" --front "$FRONT" --out "$W/x"
echo "ok"
