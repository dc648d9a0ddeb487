#!/usr/bin/env bash
# Runs "$@" on a private Xvfb server (tests that need an OpenGL context: llvmpipe under Xvfb).
# Xvfb picks a free display itself (-displayfd), so parallel ctest runs cannot race for one the way
# `xvfb-run -a` can. An existing DISPLAY is ignored on purpose: results must not depend on the GPU.
set -euo pipefail
xvfb=${XVFB:-Xvfb}
fifo_dir=$(mktemp -d)
trap 'rm -rf "$fifo_dir"' EXIT
"$xvfb" -displayfd 3 -screen 0 1280x720x24 -nolisten tcp -noreset 3>"$fifo_dir/display" \
  2>"$fifo_dir/xvfb.log" &
xvfb_pid=$!
trap 'kill "$xvfb_pid" 2>/dev/null || true; wait "$xvfb_pid" 2>/dev/null || true; rm -rf "$fifo_dir"' EXIT
for _ in $(seq 1 100); do
  [ -s "$fifo_dir/display" ] && break
  if ! kill -0 "$xvfb_pid" 2>/dev/null; then
    echo "with_xvfb.sh: Xvfb failed to start:" >&2
    cat "$fifo_dir/xvfb.log" >&2
    exit 3
  fi
  sleep 0.1
done
if [ ! -s "$fifo_dir/display" ]; then
  echo "with_xvfb.sh: Xvfb did not report a display within 10 s" >&2
  exit 3
fi
export DISPLAY=":$(head -n1 "$fifo_dir/display")"
set +e
"$@"
status=$?
exit $status
