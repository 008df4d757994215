#!/usr/bin/env bash
# The README's second command (and all that .ci/run does): install, build with warnings as errors, run
# every test (unit, GPU on lavapipe with validation, daemon integration, scale-out on PostgreSQL and
# HAProxy, browser end-to-end), then the unit tests and the daemon's integration tests (against an
# instrumented refractd) once more under AddressSanitizer + UndefinedBehaviorSanitizer with leak
# checking, then each libFuzzer target briefly.
set -euo pipefail
cd "$(dirname "$0")/.."
# The test services (PostgreSQL, HAProxy) are installed here only; tests/scale/with_postgres.sh starts and
# removes a throwaway cluster for the scale-out test (ctest's scale_out), which starts HAProxy itself.
echo "== install at $(date +%T) =="
REFRACT_TEST_SERVICES=1 bash scripts/install-deps.sh
npm --prefix tests/e2e ci --no-audit --no-fund --loglevel=error
REFRACT_CMAKE_ARGS="-DREFRACT_WERROR=ON" REFRACT_NO_BROWSER=0 bash scripts/build.sh

echo "== sanitizer build (unit tests, and the daemon under its integration tests) at $(date +%T) =="
# Line tables only (-g1): a sanitizer's report names the function, file and line from them, and full
# debug info made the build 214 s against 190 on two cores. (-O1 would run faster, but GCC 12 then warns
# of maybe-uninitialized members inside <regex>, an error here.)
cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=Debug -DCMAKE_CXX_FLAGS_DEBUG=-g1 -DREFRACT_SANITIZE=ON \
  -DREFRACT_WERROR=ON > /dev/null
cmake --build build-asan -j"$(nproc)" --target protocol_test mesh_test vk_context_test daemon_units_test refractd
# Leak checking stays on; what the Vulkan driver stack keeps until exit is suppressed by module
# (tests/lsan.supp). The loader unloads lavapipe before LeakSanitizer looks, which leaves its frames
# nameless ("<unknown module>") and so unsuppressable: preloading it keeps it mapped and named. The
# daemon's integration tests are the Release build's, started against the sanitized refractd: what they
# check is the daemon, and compiling them again with the sanitizers took longer than running them. The
# sanitized daemon runs without the Vulkan validation layer (28% of its tests' time): the suite below
# runs the same tests with it. Its tests run in two shards side by side: each starts a daemon of its own,
# they wait on sockets as much as they compute (200 -> 131 s on two cores), and against the sanitized
# daemon they assert no times.
lavapipe="$(dpkg -L mesa-vulkan-drivers | grep -m1 '/libvulkan_lvp\.so$')"
sanitized() {
  LD_PRELOAD="$lavapipe" ASAN_OPTIONS=detect_leaks=1:verify_asan_link_order=0 \
    LSAN_OPTIONS="suppressions=$PWD/tests/lsan.supp:print_suppressions=0" \
    REFRACT_SANITIZED_REFRACTD="$PWD/build-asan/server/daemon/refractd" LP_NUM_THREADS=2 "$@" --gtest_brief=1
}
for t in build-asan/tests/protocol_test build-asan/tests/mesh_test build-asan/tests/vk_context_test \
         build-asan/tests/daemon_units_test; do
  REFRACT_VALIDATION=1 sanitized "$t"
done
shards=()
for shard in 0 1; do
  GTEST_TOTAL_SHARDS=2 GTEST_SHARD_INDEX=$shard REFRACT_VALIDATION=0 sanitized build/tests/daemon_test &
  shards+=($!)
done
for pid in "${shards[@]}"; do wait "$pid"; done

echo "== fuzzing (5 s per target; scripts/fuzz.sh with no argument runs 10 minutes each) at $(date +%T) =="
bash scripts/fuzz.sh 5

# One test per CPU core at a time: many wait on sockets, Chromium or PostgreSQL as much as they compute
# (374 -> 234 s on two cores), and the few bounds on time some assert (a health check within 1 s, an
# edit beside a heavy frame within 6 s) have margins the sanitized daemon's two shards above meet.
echo "== full suite at $(date +%T) =="
cd build && ctest --output-on-failure --timeout 600 -j"$(nproc)"
