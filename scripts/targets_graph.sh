#!/usr/bin/env bash
# The project's targets and their links, drawn from CMake's own graph (cmake --graphviz):
#   BUILD/graph/targets.dot      every target, external libraries and tests included (CMake's);
#   docs/figures/targets.dot     the project's libraries and programs only (no external libraries,
#                                no test, benchmark or fuzz programs), one line per link, sorted;
#   docs/figures/targets.png     that graph drawn, where graphviz's `dot` is installed.
# Fails when the simulator reaches any relight target, directly or through another library: the
# simulated world (and its ground truth) must not depend on the method it judges.
# Usage: bash scripts/targets_graph.sh [BUILD_DIR]   (default build; configured if need be)
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
full="$build/graph/targets.dot"
mkdir -p "$build/graph" docs/figures
rm -f "$build"/graph/targets.dot*
cmake -S . -B "$build" --graphviz="$full" >/dev/null

# The project's own targets: those its CMakeLists define outside tests/, microbench/ and fuzz/.
mapfile -t own < <(git ls-files '*CMakeLists.txt' | grep -Ev '^(tests|microbench|fuzz)/' |
  xargs cat | grep -oE '^\s*(lightstage_library|add_library|add_executable)\(\s*[A-Za-z0-9_]+' |
  sed -E 's/.*\(\s*//' | sort -u)

python3 - "$full" docs/figures/targets.dot "${own[@]}" <<'EOF'
import re
import sys

full, out, own = sys.argv[1], sys.argv[2], set(sys.argv[3:])
text = open(full).read()
names = dict(re.findall(r'"(node\d+)" \[ label = "([^"]+)"', text))
shapes = dict(re.findall(r'"(node\d+)" \[ label = "[^"]+", shape = (\w+)', text))
edges = set()
for a, b, style in re.findall(r'"(node\d+)" -> "(node\d+)"(?: \[ style = (\w+) \])?', text):
    if a != b:
        edges.add((names[a], names[b], style or "solid"))

# Everything the simulator reaches, through any link.
reach, frontier = set(), ["sim"]
while frontier:
    target = frontier.pop()
    for a, b, _ in edges:
        if a == target and b not in reach:
            reach.add(b)
            frontier.append(b)
bad = sorted(t for t in reach if t.startswith("relight"))

kept = sorted(n for n in set(names.values()) if n in own)
lines = ["// The project's targets and their links (scripts/targets_graph.sh writes this from",
         "// cmake --graphviz). Solid: public link; dotted: private; dashed: interface only.",
         'digraph "lightstage" {', "  rankdir = BT;", '  node [ fontsize = "12" ];']
shape_of = {n: shapes[k] for k, n in names.items()}
for n in kept:
    lines.append(f'  "{n}" [ shape = {shape_of[n]} ];')
for a, b, style in sorted(edges):
    if a in own and b in own:
        lines.append(f'  "{a}" -> "{b}"' + ("" if style == "solid" else f" [ style = {style} ]") + ";")
lines.append("}")
open(out, "w").write("\n".join(lines) + "\n")
print(f"{out}: {len(kept)} targets; sim reaches {', '.join(sorted(t for t in reach if t in own))}")
if bad:
    print(f"sim reaches relight targets: {', '.join(bad)}", file=sys.stderr)
    sys.exit(1)
EOF

if command -v dot >/dev/null; then
  dot -Tpng -Gdpi=96 docs/figures/targets.dot -o docs/figures/targets.png
  echo "docs/figures/targets.png"
else
  echo "graphviz's dot not installed: docs/figures/targets.png not drawn (apt-get install graphviz)"
fi
