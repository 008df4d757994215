#!/usr/bin/env bash
# The one list of what Refract needs on Debian 12. README, .ci/run and docker/Dockerfile all call this.
# Idempotent and non-interactive; run as root (or with sudo available).
set -euo pipefail
export DEBIAN_FRONTEND=noninteractive
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi

# REFRACT_RUNTIME_ONLY=1: only what the built binaries need to run (the container image's final stage).
runtime=(libvulkan1 libpng16-16 libpq5 libopenexr-3-1-30 libtinygltf2d libcpp-httplib0.11 libopenvdb10.0 curl ca-certificates)

packages=(
  build-essential cmake pkg-config git ca-certificates curl
  libvulkan-dev vulkan-validationlayers vulkan-tools
  glslang-tools
  libcpp-httplib-dev nlohmann-json3-dev libpng-dev zlib1g-dev libglm-dev libgtest-dev
  libboost1.81-dev
  libpq-dev  # the shared PostgreSQL store (refractd --store postgresql://...); no server needed to build
  libstb-dev libopenexr-dev  # environment maps: Radiance .hdr (stb_image, header only) and OpenEXR
  libtinygltf-dev  # glTF 2.0 scenes in and out (server/gltf)
  libopenvdb-dev  # volume assets: OpenVDB files (server/volume), also written by the tests
  libnanovdb-dev  # volume assets: NanoVDB .nvdb files, whose layout its headers fix (header only), converted by the tests
  assimp-testmodels
  clang lld libclang-rt-14-dev  # scripts/fuzz.sh: libFuzzer (libclang_rt.fuzzer) and lld's --gc-sections
)
# Browser end-to-end test: Debian's Chromium driven by playwright-core from npm.
if [ "${REFRACT_NO_BROWSER:-0}" != "1" ]; then
  packages+=(chromium)
  # A machine may already carry Node.js from elsewhere (whose nodejs bundles npm); only add Debian's when absent.
  command -v npm >/dev/null 2>&1 || packages+=(nodejs npm)
fi

# Services only the tests start (a throwaway PostgreSQL cluster and HAProxy, tests/scale/), and PyYAML for
# the deploy/ manifests check (tests/deploy/): scripts/test.sh
# asks for them, the README's first command does not, so a new user's machine runs no database.
if [ "${REFRACT_TEST_SERVICES:-0}" = "1" ]; then
  packages+=(postgresql haproxy python3-yaml)
fi

# A reference renderer only the benchmarks run (scripts/bench-povray.sh), not the tests.
if [ "${REFRACT_BENCH_TOOLS:-0}" = "1" ]; then
  packages+=(povray python3)
fi

if [ "${REFRACT_RUNTIME_ONLY:-0}" = "1" ]; then
  packages=("${runtime[@]}")
fi

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ "${#missing[@]}" -gt 0 ]; then
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# lavapipe, the default device, from bookworm-backports (Mesa 25.0; Debian 12 itself has 22.3): its
# llvmpipe jumps over the code of a branch no invocation of a subgroup takes, which 22.3 ran for every one:
# every frame cheaper, the same to a few last bits (docs/perf-log/2026-12-07-lavapipe-from-backports.md).
# Installed here, not in the lists above, because the installed release matters, not only the name.
lavapipe_from="25.0"
installed="$(dpkg-query -W -f='${Status} ${Version}' mesa-vulkan-drivers 2>/dev/null || true)"
if [[ "$installed" != "install ok installed "* ]] || dpkg --compare-versions "${installed##* }" lt "$lavapipe_from"; then
  if ! grep -rqs "bookworm-backports" /etc/apt/sources.list /etc/apt/sources.list.d/; then
    echo "deb http://deb.debian.org/debian bookworm-backports main" |
      $SUDO tee /etc/apt/sources.list.d/bookworm-backports.list > /dev/null
  fi
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends mesa-vulkan-drivers/bookworm-backports
fi
