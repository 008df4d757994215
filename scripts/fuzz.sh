#!/usr/bin/env bash
# Builds the libFuzzer targets (fuzz/, clang with AddressSanitizer + UndefinedBehaviorSanitizer) in
# build-fuzz/ and runs each for SECONDS (default 600), starting from its seed corpus
# in fuzz/corpus/<target>/, as many at once as there are CPU cores ($REFRACT_FUZZ_JOBS overrides). New
# inputs go to build-fuzz/corpus/<target>/ (the seeds are not touched); a
# crash, leak, timeout or broken invariant leaves its input in build-fuzz/artifacts/<target>/ and fails
# the script. Usage: scripts/fuzz.sh [SECONDS] [TARGET...]
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-600}"
shift || true
targets=("$@")
if [ "${#targets[@]}" -eq 0 ]; then
  targets=(scene_document_fuzzer obj_fuzzer index_grid_fuzzer ws_message_fuzzer environment_fuzzer gltf_fuzzer density_export_fuzzer nvdb_fuzzer)
fi

CC=clang CXX=clang++ cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=Release -DREFRACT_FUZZ=ON -DREFRACT_TESTS=OFF \
  -DREFRACT_WERROR=ON > /dev/null
cmake --build build-fuzz -j"${REFRACT_FUZZ_JOBS:-$(nproc)}" --target fuzzers

# Targets run side by side, one a CPU core (each libFuzzer process is single-threaded).
jobs="${REFRACT_FUZZ_JOBS:-$(nproc)}"
: > build-fuzz/failed
fuzz_one() {
  local t="$1" corpus="build-fuzz/corpus/$1" artifacts="build-fuzz/artifacts/$1"
  mkdir -p "$corpus" "$artifacts"
  echo "== $t: ${seconds}s =="
  if ! ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1}" UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1" \
      "build-fuzz/fuzz/$t" "$corpus" "fuzz/corpus/$t" -max_total_time="$seconds" -timeout=10 \
      -rss_limit_mb=2048 -max_len=8192 -print_final_stats=1 -artifact_prefix="$artifacts/" \
      > "build-fuzz/$t.log" 2>&1; then
    echo "$t" >> build-fuzz/failed
    tail -n 40 "build-fuzz/$t.log"
  fi
  grep -E "^stat::number_of_executed_units|^stat::peak_rss_mb|^#[0-9]+.*DONE" "build-fuzz/$t.log" | sed "s/^/$t: /" || true
}
running=0
for t in "${targets[@]}"; do
  fuzz_one "$t" &
  running=$((running + 1))
  if [ "$running" -ge "$jobs" ]; then
    wait -n || true
    running=$((running - 1))
  fi
done
wait
if [ -s build-fuzz/failed ]; then
  echo "fuzzing failed: $(tr '\n' ' ' < build-fuzz/failed)(inputs in build-fuzz/artifacts/)" >&2
  exit 1
fi
echo "fuzzing clean: ${targets[*]}"
