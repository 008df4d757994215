#!/usr/bin/env bash
# The store benchmark (not a test; figures in docs/benchmarks.md): PATCH round trips, PATCH throughput
# and frames/s (scripts/bench_store.py) for
#   embedded   one refractd with the embedded file store
#   pg-direct  one refractd on PostgreSQL
#   haproxy-1  HAProxy + one replica on PostgreSQL
#   haproxy-3  HAProxy + three replicas on PostgreSQL
# Run after scripts/build.sh, with the test services installed (REFRACT_TEST_SERVICES=1
# bash scripts/install-deps.sh). It runs itself beside a throwaway cluster (tests/scale/with_postgres.sh).
#   bash scripts/bench-store.sh [SECONDS per measurement, default 5]
set -euo pipefail
cd "$(dirname "$0")/.."
if [ -z "${REFRACT_TEST_PG_URL:-}" ]; then
  exec bash tests/scale/with_postgres.sh bash scripts/bench-store.sh "$@"
fi
seconds="${1:-5}"
refractd="$PWD/build/server/daemon/refractd"
pids=()
stop_all() {
  for pid in "${pids[@]}"; do kill "$pid" 2>/dev/null || true; done
  for pid in "${pids[@]}"; do wait "$pid" 2>/dev/null || true; done
  pids=()
}
trap stop_all EXIT

# start_refractd PORT [ARGS...]: a daemon on PORT (WebSocket PORT+100), waited for.
start_refractd() {
  local port=$1; shift
  "$refractd" --port "$port" --ws-port $((port + 100)) --data-dir "$REFRACT_TEST_DIR/data-$port" \
    --max-queue 64 "$@" >"$REFRACT_TEST_DIR/refractd-$port.log" 2>&1 &
  pids+=($!)
  for _ in $(seq 100); do curl -fs "127.0.0.1:$port/api/health" >/dev/null && return; sleep 0.1; done
  echo "refractd on $port did not start" >&2; cat "$REFRACT_TEST_DIR/refractd-$port.log" >&2; exit 1
}
start_haproxy() {
  REFRACT_LISTEN=127.0.0.1:18000 haproxy -db -f deploy/haproxy/haproxy.cfg >"$REFRACT_TEST_DIR/haproxy.log" 2>&1 &
  pids+=($!)
  for _ in $(seq 100); do curl -fs 127.0.0.1:18000/api/health >/dev/null && return; sleep 0.1; done
  echo "haproxy did not start" >&2; exit 1
}

echo "machine: $(nproc) CPUs, $(lscpu | sed -n 's/^Model name: *//p'), $(date -u +%F)"
start_refractd 18101
python3 scripts/bench_store.py 127.0.0.1:18101 embedded "$seconds"
stop_all

psql "$REFRACT_TEST_PG_URL" -qc "CREATE DATABASE bench" >/dev/null
url="${REFRACT_TEST_PG_URL/\/refract\?//bench?}"
start_refractd 18101 --store "$url"
python3 scripts/bench_store.py 127.0.0.1:18101 pg-direct "$seconds"
export REFRACT_REPLICA_1=127.0.0.1:18101 REFRACT_REPLICA_2=127.0.0.1:18102 REFRACT_REPLICA_3=127.0.0.1:18103
# One replica: the other two slots point at nothing and are marked down by the health checks.
start_haproxy
sleep 1.5
python3 scripts/bench_store.py 127.0.0.1:18000 haproxy-1 "$seconds"
start_refractd 18102 --store "$url"
start_refractd 18103 --store "$url"
sleep 1.5  # two health checks: the new replicas count as up
python3 scripts/bench_store.py 127.0.0.1:18000 haproxy-3 "$seconds"
