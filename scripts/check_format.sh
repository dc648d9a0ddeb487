#!/usr/bin/env bash
# Fails listing every C++ file that clang-format would change (style: .clang-format).
set -euo pipefail
cd "$(dirname "$0")/.."
command -v clang-format >/dev/null || { echo "clang-format not installed (scripts/setup.sh installs it)"; exit 1; }
bad=()
while IFS= read -r f; do
  clang-format --dry-run -Werror "$f" >/dev/null 2>&1 || bad+=("$f")
done < <(git ls-files '*.cc' '*.h' 2>/dev/null || find lightstage physics capture relight sim viewer tests microbench -name '*.cc' -o -name '*.h')
if ((${#bad[@]})); then
  echo "not clang-formatted (run: clang-format -i FILE): ${bad[*]}"
  exit 1
fi
echo "clang-format: all files formatted"
