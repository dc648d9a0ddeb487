#!/usr/bin/env bash
# Sanitizers and fuzzing (docs/testing.md, "Sanitizers and fuzzing"). In a build directory of its
# own, configured with clang++ and LIGHTSTAGE_FUZZ=ON (cmake/Fuzzing.cmake):
#   1. builds the fuzz targets (fuzz/) and the tests named in LIGHTSTAGE_SANITIZE_TESTS under
#      AddressSanitizer + UndefinedBehaviorSanitizer;
#   2. runs those tests (ctest -L sanitize);
#   3. writes the seeds (make_fuzz_seeds) and runs every fuzz target for SECONDS, one at a time,
#      from its seeds, fuzz/corpus/<target>/ (hand-written seeds and the inputs of fixed findings)
#      and what earlier runs here found (BUILD_DIR/fuzz-corpus/<target>/).
# Exits non-zero on a failing test or any finding; a finding's input is saved as
# BUILD_DIR/fuzz-findings/<target>/crash-… (or leak-, timeout-, oom-), and the log shows its stack.
# Replay one with BUILD_DIR/fuzz/<target> FILE (LIGHTSTAGE_FUZZ_VERBOSE=1 prints the refusals).
#   scripts/fuzz.sh [TARGET...]        (default: every target; a name is e.g. lp_fuzz or lp)
#   FUZZ_SECONDS    seconds per target (default 5, what CI runs; e.g. 600 for a local run)
#   FUZZ_BUILD_DIR  build directory (default build-fuzz)
#   FUZZ_SKIP_TESTS=1  only the fuzz targets
#   FUZZ_CLI        the lightstage executable the tests that run the CLI use (default: the normal
#                   build's, build/app/cli/lightstage, which scripts/setup.sh builds)
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${FUZZ_BUILD_DIR:-build-fuzz}
SECONDS_PER_TARGET=${FUZZ_SECONDS:-5}
ALL_TARGETS=(stage_fuzz scene_fuzz session_fuzz model_edits_fuzz temporal_edits_fuzz lp_fuzz
             field_exr_fuzz model_maps_fuzz temporal_maps_fuzz rti_fuzz pca_fuzz)

command -v clang++ >/dev/null && [ -n "$(find /usr/lib/llvm-*/lib/clang -name 'libclang_rt.fuzzer-x86_64.a' 2>/dev/null)" ] ||
  { echo "fuzz: needs clang and libFuzzer (packages clang, libclang-rt-14-dev: scripts/setup.sh)"; exit 1; }

targets=()
for name in "$@"; do targets+=("${name%_fuzz}_fuzz"); done
((${#targets[@]})) || targets=("${ALL_TARGETS[@]}")

start=$(date +%s)
launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
export CCACHE_BASEDIR=${CCACHE_BASEDIR:-$PWD}  # a clone elsewhere reuses the cache
cli=${FUZZ_CLI:-$PWD/build/app/cli/lightstage}
[ -x "$cli" ] || echo "fuzz: warning: no $cli (scripts/setup.sh builds it): the tests that run the CLI will fail"
cmake -S . -B "$BUILD_DIR" -G Ninja -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=Release \
  -DLIGHTSTAGE_FUZZ=ON -DLIGHTSTAGE_BUILD_BENCHMARKS=OFF -DLIGHTSTAGE_FUZZ_CLI="$cli" \
  "${launcher[@]}" >/dev/null
echo "fuzz: building the sanitizer build in $BUILD_DIR"
cmake --build "$BUILD_DIR" --target fuzz_all -j "$(nproc)"
built=$(date +%s)
echo "fuzz: built in $((built - start)) s"

# Reports stop at the first error; UBSan prints its stack. halt_on_error is ASan's default.
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
export ASAN_OPTIONS=detect_leaks=1:strict_string_checks=1:detect_stack_use_after_return=1
scratch=$(mktemp -d "$([ -w /dev/shm ] && echo /dev/shm || echo "${TMPDIR:-/tmp}")/lightstage-fuzz.XXXXXX")
trap 'rm -rf "$scratch"' EXIT
export TMPDIR=$scratch  # The targets' and tests' temporary folders (fuzz_support.h).

if [ "${FUZZ_SKIP_TESTS:-0}" != 1 ]; then
  echo "fuzz: the sanitized tests (ctest -L sanitize)"
  ctest --test-dir "$BUILD_DIR" -L sanitize --output-on-failure -j "$(nproc)" --timeout 600
  tested=$(date +%s)
  echo "fuzz: sanitized tests passed in $((tested - built)) s"
fi

seeds="$BUILD_DIR/fuzz-seeds"
rm -rf "$seeds"
"$BUILD_DIR/fuzz/make_fuzz_seeds" "$seeds" .
failed=()
for target in "${targets[@]}"; do
  corpus="$BUILD_DIR/fuzz-corpus/$target"
  findings="$BUILD_DIR/fuzz-findings/$target"
  log="$BUILD_DIR/fuzz-logs/$target.log"
  mkdir -p "$corpus" "$findings" "$(dirname "$log")"
  dirs=("$corpus")
  for d in "$seeds/$target" "fuzz/corpus/$target"; do [ -d "$d" ] && dirs+=("$d"); done
  dict=()
  [ "$target" = pca_fuzz ] || dict=(-dict=fuzz/json.dict)
  # One input may take up to 20 s and 2.5 GB (the sanitizers' own memory included) before it
  # counts as a finding; -1 inputs (an undescribable EXR) are not kept.
  if "$BUILD_DIR/fuzz/$target" -max_total_time="$SECONDS_PER_TARGET" -timeout=20 \
      -rss_limit_mb=2560 -print_final_stats=1 -print_funcs=0 -artifact_prefix="$findings/" \
      "${dict[@]}" "${dirs[@]}" >"$log" 2>&1; then
    echo "fuzz: $target: $(grep -E '^stat::number_of_executed_units' "$log" | awk '{print $2}') inputs in ${SECONDS_PER_TARGET} s, no finding"
  else
    echo "fuzz: $target: FINDING (input saved in $findings/; log $log):"
    grep -E -A40 'ERROR: |runtime error|terminate called|Assertion|check failed' "$log" | head -60 || true
    failed+=("$target")
  fi
done
echo "fuzz: done in $(($(date +%s) - start)) s"
if ((${#failed[@]})); then
  echo "fuzz: findings in: ${failed[*]}"
  exit 1
fi
