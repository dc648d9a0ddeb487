#!/usr/bin/env bash
# clang-tidy (checks: .clang-tidy) on the C++ sources a change touched, warnings as errors, in the
# lines the change added or modified (clang-tidy-diff). The change is BASE..HEAD with BASE from
# $LIGHTSTAGE_TIDY_BASE, else .ci/tidy-base (the commit the last submission started from), else
# HEAD~1. The whole tree takes ~15 s of CPU per file (heavy headers), too long for CI's budget.
#   scripts/check_tidy.sh [BUILD_DIR]     (BUILD_DIR holds compile_commands.json; default build)
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
command -v clang-tidy-diff-14.py >/dev/null || { echo "clang-tidy not installed (scripts/setup.sh installs it)"; exit 1; }
[ -f "$build/compile_commands.json" ] || { echo "$build/compile_commands.json missing: configure first"; exit 1; }
base=${LIGHTSTAGE_TIDY_BASE:-}
[ -n "$base" ] || { [ -f .ci/tidy-base ] && base=$(tr -d '[:space:]' < .ci/tidy-base); }
git rev-parse -q --verify "${base:-HEAD~1}^{commit}" >/dev/null 2>&1 || base=HEAD~1
git rev-parse -q --verify "$base^{commit}" >/dev/null 2>&1 || { echo "clang-tidy: no base commit to compare with"; exit 0; }
# Sources only (headers are checked through them, HeaderFilterRegex); tests hold gtest macros
# that trip bugprone checks by design. Renames are followed (-M) and hunks that only change
# #include lines or comments (a file moved to another folder) are dropped: nothing to check there.
diff=$(git diff -U0 -M "$base" HEAD -- '*.cc' ':!tests/' | python3 -c '
import re, sys
out, hunk, header = [], [], []
def flush():
    global hunk
    added = [l[1:].strip() for l in hunk[1:] if l.startswith("+")]
    if any(a and not a.startswith(("#include", "//")) for a in added):
        out.extend(header); header.clear(); out.extend(hunk)
    hunk = []
for line in sys.stdin.read().split("\n"):
    if line.startswith("diff --git"):
        flush(); header[:] = [line]
    elif line.startswith("@@"):
        flush(); hunk = [line]
    elif hunk:
        hunk.append(line)
    else:
        header.append(line)
flush()
print("\n".join(out))')
files=$(printf '%s\n' "$diff" | sed -n 's|^+++ b/||p')
if [ -z "$files" ]; then echo "clang-tidy: no C++ source lines changed since $base"; exit 0; fi
echo "clang-tidy: $(echo "$files" | wc -l) changed sources since $(git rev-parse --short "$base")"
# A unity build (LIGHTSTAGE_UNITY_BUILD) lists its batches, not its sources: each source a batch
# includes gets the batch's command.
db="$build/tidy-compile-db"
mkdir -p "$db"
python3 - "$build/compile_commands.json" "$db/compile_commands.json" <<'PY'
import json, re, sys
entries = []
for e in json.load(open(sys.argv[1])):
    if "/Unity/unity_" not in e["file"]:
        entries.append(e)
        continue
    for source in re.findall(r'^#include "([^"]+)"', open(e["file"]).read(), re.M):
        entries.append(dict(e, file=source, command=e["command"].replace(e["file"], source)))
json.dump(entries, open(sys.argv[2], "w"), indent=0)
PY
printf '%s\n' "$diff" |
  clang-tidy-diff-14.py -p1 -path "$db" -j "$(nproc)" -quiet -extra-arg=-Wno-unknown-warning-option \
    -clang-tidy-binary clang-tidy-14 >"$build/clang-tidy.log" 2>&1 || true
if grep -E 'warning:|error:' "$build/clang-tidy.log"; then
  echo "clang-tidy: warnings above (full log: $build/clang-tidy.log)"
  exit 1
fi
echo "clang-tidy: clean"
