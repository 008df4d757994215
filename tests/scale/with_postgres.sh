#!/usr/bin/env bash
# Runs a command beside a throwaway PostgreSQL cluster: initdb in a fresh temp directory as an
# unprivileged user (initdb refuses root), listening only on a Unix socket in that directory, so no
# port is taken and nothing outside can connect. The command gets:
#   REFRACT_TEST_PG_URL  a libpq URL of database "refract" (user "refract", trust auth on the socket)
#   REFRACT_TEST_PG_CTL  a pg_ctl command line for that cluster (append "stop -m fast" or "start")
#   REFRACT_TEST_DIR     a scratch directory removed afterwards
# The command runs in a process group of its own; on any exit (failure, Ctrl-C) the whole group is
# killed, the cluster stopped and the directory removed.
set -euo pipefail

pg_bin="$(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -1)"
if [ -z "$pg_bin" ] || [ ! -x "$pg_bin/initdb" ]; then
  echo "with_postgres.sh: no PostgreSQL server found (REFRACT_TEST_SERVICES=1 bash scripts/install-deps.sh)" >&2
  exit 1
fi

work="$(mktemp -d /tmp/refract-pg-XXXXXX)"
as_owner=()
if [ "$(id -u)" -eq 0 ]; then
  # A user of our own rather than nobody: the cluster's files are then clearly ours.
  id refract-test >/dev/null 2>&1 || useradd --system --no-create-home --shell /usr/sbin/nologin refract-test
  chown refract-test "$work"
  chmod 755 "$work"
  as_owner=(runuser -u refract-test --)
fi
pg_ctl=("${as_owner[@]}" "$pg_bin/pg_ctl" -D "$work/data" -l "$work/postgres.log" -w -t 30)

group=""
cleanup() {
  status=$?
  if [ -n "$group" ]; then kill -KILL -- "-$group" 2>/dev/null || true; fi
  "${pg_ctl[@]}" stop -m immediate >/dev/null 2>&1 || true
  if [ "$status" -ne 0 ] && [ -f "$work/postgres.log" ]; then
    echo "--- postgres.log (last 30 lines) ---" >&2
    tail -30 "$work/postgres.log" >&2 || true
  fi
  rm -rf "$work"
  exit "$status"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

"${as_owner[@]}" "$pg_bin/initdb" -D "$work/data" -U refract --auth=trust --no-sync -E UTF8 >/dev/null
mkdir -p "$work/socket" "$work/scratch"
if [ "${#as_owner[@]}" -gt 0 ]; then chown refract-test "$work/socket"; fi
cat >> "$work/data/postgresql.conf" <<CONF
listen_addresses = ''
unix_socket_directories = '$work/socket'
max_connections = 200
fsync = on
CONF
"${pg_ctl[@]}" start >/dev/null
"${as_owner[@]}" "$pg_bin/createdb" -h "$work/socket" -U refract refract

export REFRACT_TEST_PG_URL="postgresql://refract@/refract?host=$work/socket"
export REFRACT_TEST_PG_CTL="${pg_ctl[*]}"
export REFRACT_TEST_DIR="$work/scratch"
# Without job control a background command is not a group leader, so setsid makes it one in place:
# its pid is the group to kill.
setsid "$@" &
group=$!
wait "$group"
