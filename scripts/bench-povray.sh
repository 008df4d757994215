#!/usr/bin/env bash
# Refract against POV-Ray 3.7 on the same kind of frame (not a test; figures in docs/benchmarks.md): a
# glass ball in fog lit by a spot light, 512^2, a volume caustic behind the ball. Refract renders
# examples/ball_lens_fog.json without its sky backdrop, which POV-Ray would light through the fog only by
# radiosity (`refract render`, still quality, 2^18 photons); POV-Ray renders
# scripts/povray/ball_in_fog.pov (the same scene: photons with media photons, media sampled along eye
# rays, one sample a pixel). Each is timed as a whole process, wall clock, the two alternately, ROUNDS
# times, on this machine in this run; both frames land in OUT_DIR to be looked at.
# Run after scripts/build.sh:
#   bash scripts/bench-povray.sh [ROUNDS, default 2] [OUT_DIR, default build/bench-povray]
set -euo pipefail
cd "$(dirname "$0")/.."
rounds="${1:-2}"
out="${2:-build/bench-povray}"
REFRACT_BENCH_TOOLS=1 bash scripts/install-deps.sh
refract="$PWD/build/server/cli/refract"
[ -x "$refract" ] || { echo "no $refract: run scripts/build.sh first" >&2; exit 1; }
mkdir -p "$out"
python3 - "$out/ball_in_fog.json" <<'PY'
import json, sys
scene = json.load(open("examples/ball_lens_fog.json"))
scene["environment"] = {"type": "sky", "intensity": 0}
json.dump(scene, open(sys.argv[1], "w"), indent=2)
PY

# milliseconds COMMAND...: the command's wall-clock milliseconds (its output to $out/log), or the failure.
milliseconds() {
  local start
  start=$(date +%s%N)
  "$@" >>"$out/log" 2>&1 || { echo "failed: $* (see $out/log)" >&2; exit 1; }
  echo $(( ($(date +%s%N) - start) / 1000000 ))
}

ours=() theirs=()
for round in $(seq "$rounds"); do
  ours+=("$(milliseconds "$refract" render "$out/ball_in_fog.json" -o "$out/refract.png")")
  theirs+=("$(milliseconds povray +Iscripts/povray/ball_in_fog.pov +O"$out/povray.png" +W512 +H512 -D +FN -A)")
  echo "round $round: refract ${ours[-1]} ms, POV-Ray ${theirs[-1]} ms"
done
python3 - "${ours[*]}" "${theirs[*]}" <<'PY'
import json, statistics, sys
ours = [int(x) / 1000 for x in sys.argv[1].split()]
theirs = [int(x) / 1000 for x in sys.argv[2].split()]
ratios = [t / o for o, t in zip(ours, theirs)]
spread = f"{min(ratios):.0f}" if round(min(ratios)) == round(max(ratios)) else f"{min(ratios):.0f}-{max(ratios):.0f}"
print(f"median: refract {statistics.median(ours):.2f} s, POV-Ray {statistics.median(theirs):.1f} s; "
      f"faster by {spread}x (round by round)")
print("BENCH_JSON " + json.dumps({"refract_s": ours, "povray_s": theirs, "ratios": ratios}))
PY
echo "frames: $out/refract.png, $out/povray.png"
