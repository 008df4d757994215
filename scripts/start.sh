#!/usr/bin/env bash
# The README's first command: install, build, and run refractd on 127.0.0.1:8080 with the default scene.
# Extra arguments go to refractd (e.g. --port 9000, --device NVIDIA).
set -euo pipefail
cd "$(dirname "$0")/.."
REFRACT_NO_BROWSER=1 bash scripts/build.sh
exec build/server/daemon/refractd --bind 127.0.0.1 --port 8080 "$@"
