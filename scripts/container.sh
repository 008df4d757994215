#!/usr/bin/env bash
# Builds the container image (docker/Dockerfile) with podman (or docker) and checks what it promises:
# it runs as an unprivileged user, refuses to listen beyond loopback without a token, serves
# /api/health with one, and its HEALTHCHECK passes. Needs a registry that serves debian:12 (or that
# image already pulled) and a host that can run containers.
#   bash scripts/container.sh            REFRACT_CONTAINER_ENGINE=docker to choose; REFRACT_IMAGE=name:tag
set -euo pipefail
cd "$(dirname "$0")/.."
engine="${REFRACT_CONTAINER_ENGINE:-$(command -v podman || command -v docker || true)}"
if [ -z "$engine" ]; then
  echo "container.sh: needs podman (apt-get install podman) or docker" >&2
  exit 1
fi
image="${REFRACT_IMAGE:-localhost/refract:dev}"
name="refract-check-$$"
port="${REFRACT_CONTAINER_PORT:-18080}"
cleanup() { "$engine" rm -f "$name" >/dev/null 2>&1 || true; }
trap cleanup EXIT

echo "== build $image with $engine =="
"$engine" build -f docker/Dockerfile -t "$image" .

echo "== runs as an unprivileged user =="
uid="$("$engine" run --rm --entrypoint id "$image" -u)"
[ "$uid" != 0 ] || { echo "FAIL: the image runs as root" >&2; exit 1; }
echo "uid $uid"

echo "== refuses to listen beyond loopback without a token =="
set +e
refused="$("$engine" run --rm "$image" 2>&1)"
status=$?
set -e
if [ "$status" -ne 2 ] || ! grep -q "without a token" <<<"$refused"; then
  echo "FAIL: expected exit status 2 and the reason, got $status: $refused" >&2
  exit 1
fi
echo "$refused"

echo "== serves with a token; HEALTHCHECK passes =="
"$engine" run -d --name "$name" -p "127.0.0.1:$port:8080" "$image" --token container-check >/dev/null
for _ in $(seq 60); do
  if curl -fsS "http://127.0.0.1:$port/api/health" >/dev/null 2>&1; then break; fi
  sleep 1
done
curl -fsS "http://127.0.0.1:$port/api/health"; echo
code="$(curl -s -o /dev/null -w '%{http_code}' "http://127.0.0.1:$port/api/scenes")"
[ "$code" = 401 ] || { echo "FAIL: /api/scenes without the token answered $code, not 401" >&2; exit 1; }
if [ "$(basename "$engine")" = podman ]; then
  podman healthcheck run "$name" && echo "HEALTHCHECK: healthy"
fi
echo "container.sh: image $image checked"
