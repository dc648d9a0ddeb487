#!/usr/bin/env python3
"""A unity build (LIGHTSTAGE_UNITY_BUILD, CMakeLists.txt) compiles each batch of a target's sources
as one file, so the helpers of their anonymous namespaces share one scope: two helpers of one name
either fail to compile or, worse, overload each other, and a call can silently take the other
file's (an int overload beats the double one it was written for). This lists every name that
two sources of one batch both define in an anonymous namespace; exit 1 if there is one.
  scripts/check_unity_names.py [BUILD_DIR]   (default build; needs a configured unity build)
"""
import glob
import os
import re
import sys

build = sys.argv[1] if len(sys.argv) > 1 else "build"
batches = glob.glob(os.path.join(build, "**", "Unity", "unity_*_cxx.cxx"), recursive=True)
if not batches:
    print(f"unity names: no unity batches under {build} (LIGHTSTAGE_UNITY_BUILD=OFF?): nothing to check")
    sys.exit(0)

# A definition at the start of a line (namespace contents are not indented, .clang-format):
# a return type, then the name and its opening parenthesis; or a constant.
definition = re.compile(r"^(?:static |inline |constexpr |template <[^\n]*>\s*)*"
                        r"(?:[\w:<>,*&]+ )+[*&]?(\w+)\(|^(?:static )?(?:constexpr|const) [\w:<>]+ (\w+) =")


def anonymous_names(path):
    names = set()
    depth = 0  # Anonymous namespaces open at this point.
    raw_end = None  # The end of the raw string literal (a shader's text) the line is in.
    for line in open(path, encoding="utf-8"):
        if raw_end:
            if raw_end in line:
                raw_end = None
            continue
        opened = re.search(r'R"(\w*)\(', line)
        if opened and f'){opened.group(1)}"' not in line[opened.end():]:
            raw_end = f'){opened.group(1)}"'
        if line.startswith("namespace {"):
            depth += 1
        elif depth and line.startswith("}  // namespace") and not line.startswith("}  // namespace "):
            depth -= 1
        elif depth:
            m = definition.match(line)
            if m and (m.group(1) or m.group(2)) not in ("if", "for", "while", "switch", "return"):
                names.add(m.group(1) or m.group(2))
    return names


clashes = []
for batch in sorted(batches):
    sources = re.findall(r'^#include "([^"]+)"', open(batch).read(), re.M)
    seen = {}
    for source in sources:
        for name in anonymous_names(source):
            seen.setdefault(name, []).append(os.path.relpath(source))
    target = batch.split(os.sep + "Unity")[0].rsplit(os.sep, 1)[-1].removesuffix(".dir")
    clashes += [f"{target}: {name} in {', '.join(files)}" for name, files in seen.items() if len(files) > 1]

for clash in clashes:
    print(f"unity names: {clash}")
if clashes:
    print("unity names: rename one of each (the sources share a unity batch)")
    sys.exit(1)
print(f"unity names: {len(batches)} batches, no anonymous-namespace name defined twice in one")
