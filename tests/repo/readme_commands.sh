#!/usr/bin/env bash
# Runs the shell commands of README.md as a user would, so that the README cannot drift from
# the binaries. Every ```sh block that follows a line "<!-- readme-test -->" is run, in the
# order of the README, by one bash with -e (a failing command fails the test), from the top of
# a fresh copy of the repository's files in a temporary directory, with the built `lgp` and
# `lgpd` first on PATH.
#
# Usage: readme_commands.sh SOURCE_DIR LGP_BINARY [LGPD_BINARY]
# Exit status: 0 every command succeeded, 1 a command failed or no marked block was found,
# 2 usage error.
set -uo pipefail

if (($# < 2)); then
  echo "usage: readme_commands.sh SOURCE_DIR LGP_BINARY [LGPD_BINARY]" >&2
  exit 2
fi
src="$1"
readme="$src/README.md"
if [[ ! -f "$readme" ]]; then
  echo "readme_commands: $readme: no such file" >&2
  exit 2
fi

work="$(mktemp -d "${TMPDIR:-/tmp}/lgp-readme.XXXXXX")"
trap 'rm -rf "$work"' EXIT
mkdir -p "$work/bin" "$work/repo"
ln -s "$(realpath "$2")" "$work/bin/lgp"
if (($# >= 3)); then ln -s "$(realpath "$3")" "$work/bin/lgpd"; fi

# The files a fresh clone has (tracked, plus untracked files git does not ignore); outside a
# checkout, the folders the README's commands read.
if command -v git >/dev/null 2>&1 && git -C "$src" rev-parse --show-toplevel >/dev/null 2>&1; then
  (cd "$src" && git ls-files -z --cached --others --exclude-standard) |
    (cd "$src" && xargs -0 cp --parents -t "$work/repo" 2>/dev/null)
else
  cp -r "$src/examples" "$src/README.md" "$work/repo/"
fi

# The marked blocks, in order: from a marker to the closing fence of the block after it.
awk '
  /^<!-- readme-test -->$/ { armed = 1; next }
  armed && /^```sh$/ { inside = 1; armed = 0; next }
  inside && /^```$/ { inside = 0; print ""; next }
  inside { print }
' "$readme" >"$work/commands.sh"
if ! grep -q '[^[:space:]]' "$work/commands.sh"; then
  echo "readme_commands: no \`\`\`sh block after a '<!-- readme-test -->' line in $readme" >&2
  exit 1
fi
echo "--- commands from README.md:"
cat "$work/commands.sh"
echo "---"

cd "$work/repo" || exit 1
PATH="$work/bin:$PATH" HOME="$work/home" bash -euxo pipefail "$work/commands.sh"
rc=$?
if ((rc != 0)); then
  echo "readme_commands: a README command failed (exit $rc), run from the repository root" >&2
  exit 1
fi
echo "readme_commands: every marked README command succeeded"
