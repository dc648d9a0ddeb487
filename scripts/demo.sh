#!/usr/bin/env bash
# Set up, build and run the demo on the simulated stage: capture -> field -> relit images.
# Results: demo-out/contact_sheet.png, demo-out/comparison.png, demo-out/relit/*.{exr,png}.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
exec ./build/app/cli/lightstage demo --out demo-out "$@"
