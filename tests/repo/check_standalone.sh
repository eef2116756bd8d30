#!/usr/bin/env bash
# The repository stands alone: no file in it may point at a place outside it, or at a
# document its users do not have. Every file git knows (tracked, plus untracked files that
# are not ignored) is read line by line; a line fails when it holds
#   - a relative path that climbs out of the repository (it starts with more parent steps
#     than the file is deep; steps inside a path, as in a URL, do not count), or a path into
#     a sibling "shared" folder of reference material;
#   - an absolute path of a particular machine: under the top-level work, root, mnt or
#     scratch folders, or in a home folder (home or Users) of someone other than the
#     placeholders me, user, you and name;
#   - the name of a local reference document: the upper-case PUBLISHED, TABLES or STYLE
#     markdown files, a zero-padded "seed NNN" name, or a seed file name (NNN_ + 16 hex).
# Temporary paths under /tmp and system paths (/usr, /etc) are fine. A line may opt out
# with the marker "standalone-check: allow" (for a line that has to quote such a path).
# Binary files are skipped.
#
# Usage: check_standalone.sh [SOURCE_DIR]   (default: the current directory)
# Exit status: 0 clean, 1 offending lines (each printed as file:line), 2 usage error,
# 77 skipped (git missing, or SOURCE_DIR is not the top of a git checkout).
set -uo pipefail

src="${1:-.}"
if [[ ! -d "$src" ]]; then
  echo "check_standalone: $src: not a directory" >&2
  exit 2
fi
if ! command -v git >/dev/null 2>&1; then
  echo "SKIP: git is not installed, so the tracked files cannot be listed"
  exit 77
fi
if ! top="$(git -C "$src" rev-parse --show-toplevel 2>&1)"; then
  echo "SKIP: $src is not a git checkout (e.g. an exported tarball), so there are no tracked"
  echo "      files to check. git said: $(head -n 1 <<<"$top")"
  exit 77
fi
if [[ "$(cd "$top" && pwd -P)" != "$(cd "$src" && pwd -P)" ]]; then
  echo "SKIP: $src is inside the git checkout $top but is not its top (an unpacked copy?);"
  echo "      its files are not tracked on their own, so there is nothing to check"
  exit 77
fi
cd "$top" || exit 2

list="$(mktemp)"
cand="$(mktemp)"
out="$(mktemp)"
trap 'rm -f "$list" "$cand" "$out" "$out.count"' EXIT
git ls-files -z --cached --others --exclude-standard >"$list"
nfiles="$(tr -cd '\0' <"$list" | wc -c)"

# Cheap pre-filter (a superset of every rule); awk below decides.
prefilter='\.\./|/(work|root|mnt|scratch|home|users)([^a-z0-9_.-]|$)|shared/|(published|tables|style)\.md|seed|[0-9]{3}_[0-9a-f]{16}'

# grep exits 1 when a batch has no candidate line: not an error here.
xargs -0 -a "$list" grep -s -I -H -n -i -E -e "$prefilter" -- /dev/null >"$cand" || true
awk -v countfile="$out.count" '
    BEGIN {
      h = "[0-9a-f]"
      seedfile = "[0-9][0-9][0-9]_" h h h h h h h h h h h h h h h h
    }
    {
      # grep -H -n: FILE:LINE:TEXT
      p1 = index($0, ":")
      file = substr($0, 1, p1 - 1)
      rest = substr($0, p1 + 1)
      p2 = index(rest, ":")
      line = substr(rest, 1, p2 - 1)
      text = substr(rest, p2 + 1)
      if (index(text, "standalone-check: allow")) next
      depth = gsub("/", "/", file)
      why = ""

      # Paths that climb out of the repository.
      t = text
      while (match(t, /(\.\.\/)+/)) {
        before = RSTART > 1 ? substr(t, RSTART - 1, 1) : ""
        steps = RLENGTH / 3
        # Only a path that starts with the parent steps is relative to this file.
        if (before !~ /[A-Za-z0-9_.\/~-]/ && steps > depth) {
          why = why "; relative path leaves the repository"
          break
        }
        t = substr(t, RSTART + RLENGTH)
      }
      if (text ~ /\.\.\/+shared/ || text ~ /(^|[^A-Za-z0-9_.-])shared\/(docs|seeds)([^A-Za-z0-9_]|$)/)
        why = why "; points into a shared folder outside the repository"

      # Absolute paths of one machine.
      if (text ~ /(^|[^A-Za-z0-9_.~-])\/(work|root|mnt|scratch)(\/|[^A-Za-z0-9_.-]|$)/)
        why = why "; absolute path of a particular machine"
      t = text
      while (match(t, /\/(home|Users)\/[A-Za-z0-9_.-]+/)) {
        seg = substr(t, RSTART, RLENGTH)
        sub(/^\/(home|Users)\//, "", seg)
        if (seg != "me" && seg != "user" && seg != "you" && seg != "name") {
          why = why "; absolute path into a home directory"
          break
        }
        t = substr(t, RSTART + RLENGTH)
      }

      # Local reference documents.
      if (text ~ /(^|[^A-Za-z0-9_])(PUBLISHED|TABLES|STYLE)\.md/)
        why = why "; names a local reference document (cite the publication, or docs/*.md)"
      low = tolower(text)
      if (low ~ /(^|[^a-z0-9_])seeds?[ _-]?0[0-9][0-9]([^0-9]|$)/ || match(low, seedfile))
        why = why "; names a local seed document (cite the publication instead)"

      if (why != "") {
        if (length(text) > 160) text = substr(text, 1, 157) "..."
        sub(/^[ \t]+/, "", text)
        printf "  %s:%s: %s\n      %s\n", file, line, substr(why, 3), text
        n++
      }
    }
    END { printf "%d\n", n > countfile }
  ' "$cand" >"$out"
status=$?
count="$(cat "$out.count" 2>/dev/null)"
rm -f "$out.count"
if [[ $status -ne 0 || ! "$count" =~ ^[0-9]+$ ]]; then
  echo "check_standalone: the line filter failed (awk status $status)" >&2
  exit 2
fi
if ((count > 0)); then
  echo "check_standalone: $count line(s) point outside the repository or at documents its users do not have:"
  cat "$out"
  echo "Cite publications (authors, title, venue, year) or point to docs/*.md instead."
  exit 1
fi
echo "check_standalone: $nfiles files checked; none points outside the repository"
exit 0
