#!/usr/bin/env bash
# Builds the container image (docker/Dockerfile) with podman on a machine that reaches no container
# registry, and checks what the image promises. Runs as root (re-runs itself with sudo otherwise); too slow
# for scripts/test.sh: on the team's 2-core VM a run from an empty image store took 3 min (base 22 s, build
# 152 s; builds took 152-367 s over four runs), and the image is 411 MB.
#
#  1. Tools: installs mmdebstrap, podman, buildah, runc, uidmap, fuse-overlayfs, slirp4netns, binutils and
#     curl with apt-get when missing (idempotent, like scripts/install-deps.sh).
#  2. Base image: when localhost/debian-base:12 is not in podman's store (or REFRACT_REBUILD_BASE=1),
#     bootstraps Debian 12 with `mmdebstrap --variant=minbase bookworm` from the Debian mirror(s) this
#     machine's apt already uses (read at run time from `apt-get indextargets`: bookworm, -updates,
#     -security; REFRACT_DEBIAN_MIRROR=URL to choose another) into a tarball in a temporary directory
#     outside the tree, and imports it (`podman import`). Docs, man pages and locales are left out, as in
#     Debian's "slim" images; the copyright files stay.
#  3. Runtime settings: finds the podman options this host can start a container with (the default; then
#     ulimits within the host's hard limits, for a sandbox without CAP_SYS_RESOURCE; then runc, for a
#     cgroup v1/hybrid host crun refuses) and a build isolation that works (OCI with that runtime, else
#     chroot). Prints every refusal it saw.
#  4. Build: `podman build --format docker` (HEALTHCHECK is kept only in the docker format) with
#     --build-arg BASE_IMAGE=<the base>, tagged localhost/refract:dev; prints the time it took.
#     REFRACT_SKIP_BUILD=1 checks an image already built. Leaves no intermediate images (REFRACT_BUILD_CACHE=1
#     keeps them, as layer cache).
#  5. Checked from the image itself, without running it (podman image inspect + podman image mount):
#     the configured user is refract, uid 10001 in the image's /etc/passwd, not root; the entrypoint and
#     the HEALTHCHECK are the ones docker/Dockerfile declares; /usr/local/bin/refractd, refract-vdb-check
#     (the daemon's volume check) and refract exist
#     and every shared library they need resolves inside the image (`chroot <rootfs> ldd`, fails on "not
#     found"); lavapipe's ICD json is there and names a library that is there and resolves too; the
#     browser client and every example are there; no compiler or cmake made it into the final stage.
#  6. Run checks, where the host can start containers: runs as a non-root uid; without a token it exits
#     with status 2 and says why; with one, /api/health answers (inside the container, and through the
#     published port), /api/scenes without the token is refused (401), and `podman healthcheck run`
#     passes. Where the host cannot start a container (or publish a port), it says so and why, and those
#     checks are reported as "could not run here", not as passed.
# Ends with a summary of what was CHECKED and what COULD NOT RUN HERE; exits 1 on any failed check, 0
# otherwise (REFRACT_REQUIRE_RUN=1: also 1 when a run check could not run).
#   bash scripts/container.sh        REFRACT_IMAGE=name:tag  REFRACT_BASE_IMAGE=name:tag  REFRACT_CONTAINER_PORT=18080
set -euo pipefail
cd "$(dirname "$0")/.."
if [ "$(id -u)" -ne 0 ]; then exec sudo -E bash "$0" "$@"; fi
export DEBIAN_FRONTEND=noninteractive

image="${REFRACT_IMAGE:-localhost/refract:dev}"
base="${REFRACT_BASE_IMAGE:-localhost/debian-base:12}"
suite=bookworm
port="${REFRACT_CONTAINER_PORT:-18080}"
name="refract-check-$$"
work="$(mktemp -d "${TMPDIR:-/tmp}/refract-container.XXXXXX")"
root=""
checked=()
not_run=()
failed=()
cleanup() {
  podman rm -f "$name" >/dev/null 2>&1 || true
  if [ -n "$root" ]; then podman image unmount "$image" >/dev/null 2>&1 || true; fi
  rm -rf "$work"
}
trap cleanup EXIT
ok() { echo "CHECKED: $*"; checked+=("$*"); }
bad() { echo "FAIL: $*" >&2; failed+=("$*"); }            # a failed check: the others still run
fail() { echo "FAIL: $*" >&2; exit 1; }                     # nothing further can be checked
cannot() { echo "COULD NOT RUN HERE: $*"; not_run+=("$*"); }
summary() {
  echo
  echo "== summary for $image =="
  for c in "${checked[@]+"${checked[@]}"}"; do echo "  checked:             $c"; done
  for c in "${not_run[@]+"${not_run[@]}"}"; do echo "  could not run here:  $c"; done
  for c in "${failed[@]+"${failed[@]}"}"; do echo "  FAILED:              $c"; done
  if [ "${#failed[@]}" -gt 0 ]; then
    echo "container.sh: ${#failed[@]} check(s) failed" >&2
    exit 1
  fi
  if [ "${#not_run[@]}" -gt 0 ] && [ "${REFRACT_REQUIRE_RUN:-0}" = 1 ]; then
    echo "container.sh: REFRACT_REQUIRE_RUN=1 and some checks could not run here" >&2
    exit 1
  fi
  echo "container.sh: every check that could run here passed"
}

echo "== tools =="
tools=(mmdebstrap podman buildah runc crun uidmap fuse-overlayfs slirp4netns binutils curl ca-certificates)
missing=()
for p in "${tools[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ "${#missing[@]}" -gt 0 ]; then
  echo "installing ${missing[*]}"
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
podman --version
echo "storage driver: $(podman info --format '{{.Store.GraphDriverName}}')"

echo "== base image $base =="
if [ "${REFRACT_REBUILD_BASE:-0}" = 1 ] || ! podman image exists "$base"; then
  # The Debian archive(s) apt already uses, whatever the host's own release: apt's view of its sources
  # (one-line or deb822 files alike), keeping the entries of Debian suites (bookworm, bookworm-updates,
  # bookworm-security on a bookworm host). No host name is written here.
  mirrors=()
  if [ -n "${REFRACT_DEBIAN_MIRROR:-}" ]; then
    mirrors=("deb ${REFRACT_DEBIAN_MIRROR} $suite main")
  else
    host_suite="$(. /etc/os-release && echo "${VERSION_CODENAME:-$suite}")"
    while read -r uri release; do
      mirrors+=("deb $uri $suite${release#"$host_suite"} main")
    done < <(apt-get indextargets --format '$(REPO_URI) $(RELEASE)' 'Created-By: Packages' \
               | awk -v s="$host_suite" '$2 ~ ("^" s "(-updates|-security)?$")' | sort -u)
  fi
  [ "${#mirrors[@]}" -gt 0 ] || fail "no Debian mirror in this machine's apt sources; set REFRACT_DEBIAN_MIRROR=URL"
  printf '  %s\n' "${mirrors[@]}"
  start=$SECONDS
  mmdebstrap --variant=minbase --quiet \
    --dpkgopt='path-exclude=/usr/share/man/*' --dpkgopt='path-exclude=/usr/share/info/*' \
    --dpkgopt='path-exclude=/usr/share/locale/*' --dpkgopt='path-exclude=/usr/share/doc/*' \
    --dpkgopt='path-include=/usr/share/doc/*/copyright' \
    "$suite" "$work/rootfs.tar" "${mirrors[@]}"
  podman import --quiet --message "mmdebstrap --variant=minbase $suite (scripts/container.sh)" \
    --change 'ENV PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin' \
    --change 'CMD ["bash"]' "$work/rootfs.tar" "$base" >/dev/null
  rm -f "$work/rootfs.tar"
  echo "bootstrapped and imported in $((SECONDS - start)) s"
fi
podman image ls "$base"

echo "== which container settings this host allows =="
# A sandbox without CAP_SYS_RESOURCE cannot raise RLIMIT_NOFILE/NPROC to podman's defaults; crun refuses
# a cgroup v1/hybrid host ("cgroups in hybrid mode not supported"), runc does not.
nofile="$(ulimit -Hn)"
[ "$nofile" = unlimited ] || [ "$nofile" -le 65536 ] || nofile=65536
limits="--ulimit nofile=$nofile:$nofile --ulimit nproc=4096:4096"
run_opts=""
can_run=0
why=""
for candidate in "" "$limits" "--runtime runc" "--runtime runc $limits"; do
  # shellcheck disable=SC2086
  if out="$(podman run --rm $candidate "$base" true 2>&1)"; then
    run_opts="$candidate"; can_run=1; break
  fi
  echo "  podman run ${candidate:-(defaults)}: $out"
  why="$out"
done
if [ "$can_run" = 1 ]; then
  echo "containers start with: podman run ${run_opts:-(defaults)}"
else
  echo "no setting tried starts a container here (last: $why)"
fi
build_opts=""
printf 'FROM %s\nRUN true\n' "$base" >"$work/Probe"
runtime_opt=""
case "$run_opts" in *"--runtime runc"*) runtime_opt="--runtime runc" ;; esac
for candidate in "--isolation oci $runtime_opt" "--isolation chroot"; do
  # shellcheck disable=SC2086
  if out="$(podman build $candidate -f "$work/Probe" -t localhost/refract-probe:tmp "$work" 2>&1)"; then
    build_opts="$candidate"; break
  fi
  echo "  podman build $candidate: $(tail -1 <<<"$out")"
done
podman rmi -f localhost/refract-probe:tmp >/dev/null 2>&1 || true
[ -n "$build_opts" ] || fail "podman build cannot run a RUN step here with any isolation tried"
echo "builds with: podman build $build_opts"

if [ "${REFRACT_SKIP_BUILD:-0}" != 1 ]; then
  echo "== build $image from docker/Dockerfile on $base ($(nproc) cores) =="
  start=$SECONDS
  # shellcheck disable=SC2086
  # --layers=false: no intermediate images left behind (the build stage alone is 1.8 GB, and its cache
  # rarely helps, since the build context is the whole tree); REFRACT_BUILD_CACHE=1 keeps them.
  layers="--layers=false"
  if [ "${REFRACT_BUILD_CACHE:-0}" = 1 ]; then layers="--layers=true"; fi
  podman build $build_opts $layers --format docker --build-arg "BASE_IMAGE=$base" -f docker/Dockerfile -t "$image" .
  echo "built in $((SECONDS - start)) s"
fi
podman image exists "$image" || fail "no image $image (REFRACT_SKIP_BUILD=1 needs one already built)"
size="$(podman image inspect --format '{{.Size}}' "$image")"
echo "image $image: $((size / 1000000)) MB (base $base: $(( $(podman image inspect --format '{{.Size}}' "$base") / 1000000 )) MB)"

echo "== the image's configuration, against docker/Dockerfile =="
podman image inspect "$image" >"$work/inspect.json"
if python3 - "$work/inspect.json" docker/Dockerfile <<'EOF'
import json, re, shlex, sys
config = json.load(open(sys.argv[1]))[0]
dockerfile = open(sys.argv[2]).read()
def declared(name):
    return [l for l in dockerfile.replace("\\\n", " ").splitlines() if l.startswith(name + " ")][-1][len(name) + 1:].strip()
errors = []
user = config["Config"].get("User", "")
if user != declared("USER"):
    errors.append(f"User is {user!r}, the Dockerfile says {declared('USER')!r}")
entrypoint = config["Config"].get("Entrypoint")
if entrypoint != json.loads(declared("ENTRYPOINT")):
    errors.append(f"Entrypoint is {entrypoint}, the Dockerfile says {declared('ENTRYPOINT')}")
health = config.get("Healthcheck") or config.get("HealthCheck") or config["Config"].get("Healthcheck")
spec = declared("HEALTHCHECK")
command = spec[spec.index("CMD ") + 4:]
if not health:
    errors.append("no HEALTHCHECK in the image (built in the OCI format?)")
else:
    if health["Test"] != ["CMD-SHELL", command]:
        errors.append(f"HEALTHCHECK runs {health['Test']}, the Dockerfile says {command!r}")
    for option, field in (("interval", "Interval"), ("timeout", "Timeout"), ("start-period", "StartPeriod")):
        m = re.search(rf"--{option}=(\d+)s", spec)
        if m and health.get(field) != int(m.group(1)) * 10**9:
            errors.append(f"HEALTHCHECK {option} is {health.get(field)} ns, the Dockerfile says {m.group(1)} s")
ports = sorted(config["Config"].get("ExposedPorts", {}))
if ports != sorted(p + "/tcp" for p in declared("EXPOSE").split()):
    errors.append(f"exposed ports {ports}, the Dockerfile says {declared('EXPOSE')}")
if errors:
    print("\n".join(errors)); sys.exit(1)
print(f"User {user}; Entrypoint {shlex.join(entrypoint)}")
print(f"HEALTHCHECK {health['Test'][1]} (every {health['Interval'] // 10**9} s, timeout {health['Timeout'] // 10**9} s, "
      f"start period {health['StartPeriod'] // 10**9} s); exposes {', '.join(ports)}")
EOF
then ok "user, entrypoint, HEALTHCHECK and exposed ports are those docker/Dockerfile declares"
else bad "the image's user, entrypoint, HEALTHCHECK or ports differ from docker/Dockerfile (above)"
fi

echo "== the image's root filesystem =="
root="$(podman image mount "$image")"
echo "mounted at $root"
passwd="$(grep '^refract:' "$root/etc/passwd" || true)"
if [ "$(cut -d: -f3 <<<"$passwd")" != 10001 ]; then bad "no user refract with uid 10001 in the image's /etc/passwd: '$passwd'"
elif [ "$(stat -c %u "$root/var/lib/refract" 2>/dev/null)" != 10001 ]; then bad "/var/lib/refract is not owned by uid 10001"
else ok "user refract is uid 10001 (not root) in /etc/passwd and owns /var/lib/refract: $passwd"
fi

resolves() {  # every shared library $1 (a path inside the image) needs is found by the image's own loader
  local deps
  if ! deps="$(chroot "$root" /usr/bin/ldd "$1" 2>&1)"; then bad "ldd $1 inside the image: $deps"; return 1; fi
  if grep -q "not found" <<<"$deps"; then
    bad "$1 needs libraries the image lacks: $(grep 'not found' <<<"$deps" | tr -s ' \t\n' ' ')"; return 1
  fi
  echo "$1: $(grep -c '=>' <<<"$deps") shared libraries, all inside the image"
}
for bin in /usr/local/bin/refractd /usr/local/bin/refract-vdb-check /usr/local/bin/refract; do
  if [ ! -x "$root$bin" ]; then bad "$bin is missing or not executable in the image"
  elif resolves "$bin"; then ok "$bin is there and every shared library it needs resolves inside the image"
  fi
done

icd="$(find "$root/usr/share/vulkan/icd.d" -name "lvp_icd.*.json" 2>/dev/null | head -1)"
lvp=""
if [ -n "$icd" ]; then
  lvp="$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["ICD"]["library_path"])' "$icd")"
  case "$lvp" in /*) ;; *) lvp="$(chroot "$root" /sbin/ldconfig -p | awk -v l="$lvp" '$1 == l {print $NF; exit}')" ;; esac
fi
loader="$(find "$root/usr/lib" -name libvulkan.so.1 2>/dev/null | head -1)"
if [ -z "$icd" ]; then bad "no lavapipe ICD json (/usr/share/vulkan/icd.d/lvp_icd.*.json) in the image"
elif [ -z "$lvp" ] || [ ! -e "$root$lvp" ]; then bad "the lavapipe ICD ${icd#"$root"} names a library the image lacks"
elif [ -z "$loader" ]; then bad "no Vulkan loader (libvulkan.so.1) in the image"
elif resolves "$lvp"; then ok "lavapipe: ${icd#"$root"} names $lvp, which is there and resolves; the Vulkan loader ${loader#"$root"} is there"
fi

# Every file of web-client/ and examples/ is in the image (names only: the tree may have moved on since).
lacking=""
for dir in web-client examples; do
  lacking+="$(comm -23 <(cd "$dir" && find . -type f | sort) \
                       <(cd "$root/usr/share/refract/$dir" 2>/dev/null && find . -type f | sort) | sed "s|^\.|$dir|")"
done
if [ -n "$lacking" ]; then bad "/usr/share/refract lacks: $(tr '\n' ' ' <<<"$lacking")"
else ok "the browser client ($(find "$root/usr/share/refract/web-client" -type f | wc -l) files) and the examples ($(find "$root/usr/share/refract/examples" -name '*.json' | wc -l) scenes) are in /usr/share/refract, every file of the tree's"
fi

carried=""
for tool in cmake c++ g++ gcc clang glslangValidator; do
  if [ -e "$root/usr/bin/$tool" ]; then carried+=" /usr/bin/$tool"; fi
done
if [ -n "$carried" ]; then bad "the final stage carries build tools:$carried"
else ok "no compiler, cmake or glslang in the final stage"
fi
podman image unmount "$image" >/dev/null
root=""

echo "== run checks =="
if [ "$can_run" != 1 ]; then
  cannot "run as a non-root uid, refusal without a token, /api/health, 401 without the token, HEALTHCHECK: no container starts on this host: $why"
  summary
  exit 0
fi
# shellcheck disable=SC2086
uid="$(podman run --rm $run_opts --no-healthcheck --entrypoint id "$image" -u 2>"$work/run.err")" || uid="$(cat "$work/run.err")"
if [ "$uid" = 10001 ]; then ok "the container runs as uid $uid"; else bad "the container runs as uid $uid, not 10001"; fi

# shellcheck disable=SC2086
if version="$(podman run --rm $run_opts --no-healthcheck --entrypoint refract "$image" --version 2>&1)"; then
  ok "the refract CLI runs in the image: $version"
else
  bad "refract --version in the image: $version"
fi

set +e
# shellcheck disable=SC2086
refused="$(podman run --rm $run_opts --no-healthcheck "$image" 2>&1)"
status=$?
set -e
if [ "$status" -eq 2 ] && grep -q "without a token" <<<"$refused"; then
  ok "without a token it exits with status 2: $(grep "without a token" <<<"$refused" | head -1)"
else
  bad "expected exit status 2 and the reason without a token, got $status: $refused"
fi

# shellcheck disable=SC2086
podman run -d $run_opts --name "$name" -p "127.0.0.1:$port:8080" "$image" --token container-check >/dev/null \
  2>"$work/run.err" || { cat "$work/run.err" >&2; fail "podman run -d $image --token ... failed"; }
# podman runs the HEALTHCHECK on a schedule through a systemd timer; without systemd (a sandbox) it says
# so and schedules nothing, and `podman healthcheck run` below is the check.
if grep -q "systemd" "$work/run.err"; then
  cannot "podman's scheduled HEALTHCHECK (every 15 s): $(grep -m1 -o 'unable to get systemd connection[^"]*' "$work/run.err"); ran it by hand instead"
fi
health=""
for _ in $(seq 90); do
  if health="$(podman exec "$name" curl -fsS http://127.0.0.1:8080/api/health 2>/dev/null)"; then break; fi
  health=""
  [ "$(podman inspect --format '{{.State.Running}}' "$name")" = true ] || break
  sleep 1
done
if [ -z "$health" ]; then
  podman logs "$name" >&2 || true
  bad "/api/health did not answer inside the container with a token (running: $(podman inspect --format '{{.State.Running}}' "$name"))"
  summary
  exit 1
fi
ok "with a token /api/health answers inside the container: $health"

if curl -fsS --max-time 5 "http://127.0.0.1:$port/api/health" >/dev/null 2>"$work/curl.err"; then
  ok "/api/health answers through the published port 127.0.0.1:$port"
  code="$(curl -s -o /dev/null -w '%{http_code}' "http://127.0.0.1:$port/api/scenes")"
  where="through the published port"
else
  cannot "the published port 127.0.0.1:$port ($(cat "$work/curl.err")); checked 401 from inside the container"
  code="$(podman exec "$name" curl -s -o /dev/null -w '%{http_code}' http://127.0.0.1:8080/api/scenes)"
  where="inside the container"
fi
authorized="$(podman exec "$name" curl -s -o /dev/null -w '%{http_code}' -H 'Authorization: Bearer container-check' \
                http://127.0.0.1:8080/api/scenes)"
if [ "$code" = 401 ] && [ "$authorized" = 200 ]; then
  ok "/api/scenes without the token is refused (401, $where); with it, 200"
else
  bad "/api/scenes answered $code without the token (not 401) or $authorized with it (not 200)"
fi

if out="$(podman healthcheck run "$name" 2>&1)"; then
  ok "podman healthcheck run: healthy"
else
  bad "podman healthcheck run: $out"
fi
summary
