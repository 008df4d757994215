#!/usr/bin/env bash
# Installs Refract's dependencies (scripts/install-deps.sh) and builds it in Release into build/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release ${REFRACT_CMAKE_ARGS:-}
cmake --build build -j"$(nproc)"
