#!/usr/bin/env bash
# Shows that check_standalone.sh can fail: in a scratch git repository it must pass on clean
# files, fail on each kind of offending line (naming file:line), check untracked files that
# are not ignored, leave ignored ones alone, and skip a directory that is not a checkout.
# The offending strings are assembled from pieces so that this file itself stays clean.
# Usage: check_standalone_selftest.sh PATH/TO/check_standalone.sh
set -uo pipefail

checker="${1:?usage: check_standalone_selftest.sh PATH/TO/check_standalone.sh}"
if ! command -v git >/dev/null 2>&1; then
  echo "SKIP: git is not installed"
  exit 77
fi
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
repo="$tmp/repo"
mkdir -p "$repo/docs" "$repo/src/deep"
git init -q "$repo" || exit 2

failures=0
fail() {
  echo "FAIL: $*"
  failures=$((failures + 1))
}
run() {  # run the checker on the scratch repo; sets out and rc
  out="$(bash "$checker" "$repo" 2>&1)"
  rc=$?
}

up=".."
sh="shared"
# Clean content: paths inside the repository, placeholders, RNG seeds, /tmp.
cat >"$repo/README.md" <<EOF
See docs/tables.md and the table in src/deep/x.json.
lgp run cfg.json --seed 7 --out /tmp/q     (search.seed 1; seeds 1..400)
"data_base_dir": "/home/me/tables"
EOF
echo "Back to the top: $up/README.md" >"$repo/docs/guide.md"
echo "{\"scene\": \"$up/$up/README.md\"}" >"$repo/src/deep/x.json"
(cd "$repo" && git add -A) || exit 2

run
[[ $rc -eq 0 ]] || fail "clean tree: expected status 0, got $rc: $out"

# Each offending line, with the file:line the checker must report.
check_case() {  # name file line-number content
  local name="$1" file="$2" lineno="$3" content="$4"
  local keep
  keep="$(cat "$repo/$file" 2>/dev/null)"
  mkdir -p "$(dirname "$repo/$file")"
  {
    [[ -n "$keep" ]] && printf '%s\n' "$keep"
    printf '%s\n' "$content"
  } >"$repo/$file.new"
  mv "$repo/$file.new" "$repo/$file"
  (cd "$repo" && git add -A) || exit 2
  run
  if [[ $rc -ne 1 ]]; then
    fail "$name: expected status 1, got $rc: $out"
  elif ! grep -q "^  $file:$lineno: " <<<"$out"; then
    fail "$name: $file:$lineno not reported: $out"
  fi
  # restore
  if [[ -n "$keep" ]]; then printf '%s\n' "$keep" >"$repo/$file"; else rm -f "$repo/$file"; fi
  (cd "$repo" && git add -A) || exit 2
}

check_case "sibling shared folder" README.md 4 "Formulas: $up/$sh/docs/PUB.md"
check_case "shared folder path" src/a.hpp 1 "// see $sh/seeds/README"
check_case "relative path leaving the repository" docs/guide.md 2 "See $up/$up/elsewhere/notes.txt"
check_case "absolute machine path" src/b.cpp 1 "// spec in /wo""rk/main/spec.txt"
check_case "root home" src/c.json 1 "{\"path\": \"/ro""ot/data.csv\"}"
check_case "user home" src/d.md 1 "table at /ho""me/alice/tables/x.csv"
check_case "local document name" src/e.hpp 1 "// constants from TABLES"".md"
check_case "seed document number" src/f.cpp 1 "// Se""ed 000 section 6"
check_case "seed document file" src/g.txt 1 "read 004_b4ff99a1""d132dc9b.txt first"

# Untracked but not ignored: checked. Ignored: not checked.
printf '%s\n' "/ignored/" >"$repo/.gitignore"
mkdir -p "$repo/ignored"
echo "see $up/$sh/docs/x" >"$repo/ignored/notes.md"
(cd "$repo" && git add .gitignore) || exit 2
run
[[ $rc -eq 0 ]] || fail "ignored file: expected status 0, got $rc: $out"
echo "see $up/$sh/docs/x" >"$repo/untracked.md"
run
if [[ $rc -ne 1 ]] || ! grep -q "^  untracked.md:1: " <<<"$out"; then
  fail "untracked file: expected untracked.md:1 to be reported (status $rc): $out"
fi
rm -f "$repo/untracked.md"

# The opt-out marker.
echo "Never write $up/$sh here.  <!-- standalone-check: allow -->" >>"$repo/docs/guide.md"
(cd "$repo" && git add -A) || exit 2
run
[[ $rc -eq 0 ]] || fail "allow marker: expected status 0, got $rc: $out"

# Not a checkout: skipped with a message and status 77.
mkdir -p "$tmp/plain"
out="$(bash "$checker" "$tmp/plain" 2>&1)"
rc=$?
if [[ $rc -ne 77 ]] || ! grep -q "^SKIP:" <<<"$out"; then
  fail "plain directory: expected SKIP and status 77, got $rc: $out"
fi

if ((failures > 0)); then
  echo "check_standalone self-test: $failures failure(s)"
  exit 1
fi
echo "check_standalone self-test: all cases behave"
exit 0
