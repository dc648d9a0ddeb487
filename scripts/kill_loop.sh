#!/usr/bin/env bash
# Kill loop: a real-time simulated capture with a dead LED is killed with SIGKILL at
# random moments (inside brackets, during resumes) KILLS times, resumed until complete, then
# compared with an uninterrupted capture: every frame byte-identical, the dead LED flagged.
#   scripts/kill_loop.sh [KILLS=20] [WORK_DIR=/tmp/lightstage-kill-loop]
set -euo pipefail
cd "$(dirname "$0")/.."
kills=${1:-20}
work=${2:-/tmp/lightstage-kill-loop}
cli=${LIGHTSTAGE_CLI:-build/app/cli/lightstage}
rm -rf "$work" && mkdir -p "$work"
"$cli" stage --write "$work/default.json" >/dev/null
# 64x64 frames that take their exposure time; the LED highest on the dome never lights.
python3 - "$work" <<'PY'
import json, sys
work = sys.argv[1]
stage = json.load(open(f"{work}/default.json"))
dead = max(stage["leds"], key=lambda led: led["direction"][1])["id"]
stage["camera"].update(width=64, height=64)
stage["camera"]["simulated_sensor"].update(real_time=True, dead_leds=[dead])
json.dump(stage, open(f"{work}/stage.json", "w"))
open(f"{work}/dead_id", "w").write(str(dead))
PY
dead=$(cat "$work/dead_id")
"$cli" capture --stage "$work/stage.json" --out "$work/reference" --quiet
killed=0 resumed=0
args=(--stage "$work/stage.json" --out "$work/killed")
while ((killed < kills)); do
  "$cli" capture "${args[@]}" --quiet >>"$work/runs.log" 2>&1 &
  pid=$!
  sleep "$(python3 -c 'import random; print(random.uniform(0.1, 0.8))')"
  if kill -9 "$pid" 2>/dev/null; then killed=$((killed + 1)); fi
  wait "$pid" 2>/dev/null || true
  args=(--resume "$work/killed")
done
until "$cli" capture --resume "$work/killed" --quiet >>"$work/runs.log" 2>&1; do resumed=$((resumed + 1)); done
status=0
for f in "$work"/reference/frames/*.png; do
  cmp -s "$f" "$work/killed/frames/$(basename "$f")" || { echo "differs: $(basename "$f")"; status=1; }
done
extra=$(comm -13 <(ls "$work/reference/frames") <(ls "$work/killed/frames") | wc -l)
flagged=$(grep -c "\"dead_led\":$dead\b" "$work/killed/frames.jsonl" || true)
frames=$(ls "$work/reference/frames" | wc -l)
echo "kills: $killed; frames: $frames compared, $extra stray files; LED $dead flagged dead: $flagged"
[ "$extra" -eq 0 ] && [ "$flagged" -ge 1 ] && exit $status
exit 1
