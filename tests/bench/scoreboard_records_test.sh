#!/bin/bash
# The scoreboard run table by table (issue 32): records in <out>/tables make the same board as
# one invocation over the same tables; --report-only rebuilds it and --re-emit its code; records
# with other settings and broken records are left out with a message, never a crash.
# Usage: scoreboard_records_test.sh <lgp_scoreboard>
set -u
SB=$1
W=$(mktemp -d)
trap 'rm -rf "$W"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
run() { "$SB" --quick --no-vulkan --cache-dir "$W/cache" "$@" >"$W/out.txt" 2>"$W/err.txt"; }
# Two boards agree but for the wall time each search took (measured, so never equal), also
# where the summary quotes it.
unwalled() { grep -v '"wall_s"' "$1" | sed -E 's/[0-9.]+ s of wall time/N s of wall time/'; }
same() { cmp -s <(unwalled "$1") <(unwalled "$2"); }

run --tables sheen,fresnel_avg --out "$W/one" || fail "one invocation: $(cat "$W/err.txt")"
run --tables fresnel_avg --out "$W/two" || fail "fresnel_avg alone: $(cat "$W/err.txt")"
grep -q "Not yet run.*sheen" "$W/two/report.md" || fail "a partial board does not name what is missing"
grep -q "1 of 12 tables run so far" "$W/two/report.md" || fail "a partial board's summary does not say so"
run --tables sheen --out "$W/two" || fail "sheen alone: $(cat "$W/err.txt")"
same "$W/one/summary.json" "$W/two/summary.json" ||
  fail "table by table differs from one invocation: $(diff <(unwalled "$W/one/summary.json") <(unwalled "$W/two/summary.json") | head -20)"
for t in sheen fresnel_avg; do
  test -s "$W/two/tables/$t.json" || fail "no record for $t"
  test -s "$W/two/tables/$t.front.0.005min.json" || fail "no front for $t at 0.005 min"
done
# Fronts are committed: no absolute path of the machine that ran them.
if grep -l -E '"(config_dir|front_json|front_csv|checkpoint)": "/' "$W"/two/tables/*.front.*.json; then
  fail "a front holds an absolute path"
fi

rm "$W/two/summary.json" "$W/two/report.md"
run --report-only --out "$W/two" || fail "--report-only: $(cat "$W/err.txt")"
same "$W/one/summary.json" "$W/two/summary.json" || fail "--report-only rebuilds another board"
grep -q "| sheen | MaterialX sheen albedo (" "$W/two/report.md" || fail "--report-only lost a row"

run --report-only --seed 2 --out "$W/two" && fail "--report-only with no matching record succeeded"
grep -q "no record with these settings" "$W/err.txt" || fail "no reason given: $(cat "$W/err.txt")"

# --re-emit writes a record's recommended code again from its saved front, as the run wrote it.
rm "$W/two/sheen_recommended.glsl"
run --re-emit --tables sheen --out "$W/two" || fail "--re-emit: $(cat "$W/err.txt")"
cmp -s "$W/one/sheen_recommended.glsl" "$W/two/sheen_recommended.glsl" ||
  fail "--re-emit wrote other code: $(diff "$W/one/sheen_recommended.glsl" "$W/two/sheen_recommended.glsl" | head)"
same "$W/one/summary.json" "$W/two/summary.json" || fail "--re-emit changed the board"
run --re-emit --seed 2 --out "$W/two" && fail "--re-emit with no matching record succeeded"
grep -q "no record with these settings" "$W/err.txt" || fail "--re-emit: no reason given: $(cat "$W/err.txt")"
mv "$W/two/tables/sheen.front.0.005min.json" "$W/sheen.front"
run --re-emit --tables sheen --out "$W/two" && fail "--re-emit without the saved front succeeded"
grep -q "sheen.front.0.005min.json: cannot open" "$W/err.txt" || fail "--re-emit: no missing front named: $(cat "$W/err.txt")"
mv "$W/sheen.front" "$W/two/tables/sheen.front.0.005min.json"

echo '{"format": "lgp-scoreboard-table/1", "spec": {' >"$W/two/tables/zh.json"
run --report-only --out "$W/two" || fail "a broken record stopped the report: $(cat "$W/err.txt")"
grep -q "record left out: .*zh.json" "$W/err.txt" || fail "a broken record was not reported"
same "$W/one/summary.json" "$W/two/summary.json" || fail "a broken record changed the board"

# The edge objective is a board of its own, and its summary says so.
run --tables sheen --edge-objective --out "$W/edges" || fail "--edge-objective: $(cat "$W/err.txt")"
test -s "$W/edges/tables/sheen.edges.json" || fail "no edge-objective record"
grep -q "with the edge objective" "$W/edges/report.md" || fail "the edge board's summary does not say so"
grep -q "with the edge objective" "$W/one/report.md" && fail "the plain board claims the edge objective"
# A table whose grid spans its declared domain (fresnel_avg) has no edge rows: searched as it is.
run --tables fresnel_avg --edge-objective --out "$W/edges" || fail "--edge-objective on fresnel_avg: $(cat "$W/err.txt")"
grep -q "the grid spans the declared domain: no edge rows" "$W/edges/report.md" ||
  fail "the edge board does not say fresnel_avg had no edge rows"

run --tables nosuch --out "$W/two" && fail "an unknown table was accepted"
grep -q "'nosuch' is not a table of the spec" "$W/err.txt" || fail "unknown table: $(cat "$W/err.txt")"
echo "scoreboard records: ok"
