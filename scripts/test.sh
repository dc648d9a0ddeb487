#!/usr/bin/env bash
# Set up, build and run the whole test suite, then the sanitizer build and the fuzz targets
# (scripts/fuzz.sh: its own build directory, build-fuzz; FUZZ_SECONDS per target, default 5;
# FUZZ=0 leaves it out).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
(cd build && ctest --output-on-failure -j "$(nproc)" --timeout 900)
[ "${FUZZ:-1}" = 0 ] || bash scripts/fuzz.sh
