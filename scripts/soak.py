#!/usr/bin/env python3
"""Soak a refractd: frames of every edit kind, and the daemon's RSS, open files, threads and executable
mappings over time (read from /proc, so the daemon must run on this machine).

  python3 scripts/soak.py --refractd build/server/daemon/refractd --minutes 3
  python3 scripts/soak.py --url http://127.0.0.1:8080 --pid 1234 --frames 200 --edits camera

With --refractd the script starts the daemon (a fresh data directory, a free port) and stops it at the
end; with --url and --pid it drives one already running. Each frame is one POST of a merge patch to
/api/scenes/ID/frame.png on a small scene of its own. Prints one line per sample and, with --json, the
samples as JSON at the end. Python's standard library only.
"""

import argparse
import http.client
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.parse

# Edit kinds, each a function of the frame number giving a merge patch, and what it reruns
# (server/render/invalidation.cpp). Values alternate, so every frame is a real edit.
EDITS = {
    "camera": lambda i: {"camera": {"position": [0.3 * (1 if i % 2 else -1), 0.5, 5.0]}},
    "light": lambda i: {"light": {"position": [2.0 + 0.2 * (i % 3), 3.0, 1.0]}},
    "photons": lambda i: {"photons": {"count": 8192 if i % 2 else 16384}},
    "extinction": lambda i: {"medium": {"extinction": [0.2, 0.2, 0.2] if i % 2 else [0.2, 0.22, 0.25]}},
    "scattering": lambda i: {"medium": {"scattering": [0.2, 0.2, 0.2] if i % 2 else [0.15, 0.15, 0.15]}},
    "phase": lambda i: {"medium": {"phase": {"g": 0.3 if i % 2 else 0.5}}},
    "ior": lambda i: {"object": {"ior": 1.45 if i % 2 else 1.5}},
    "abbe": lambda i: {"object": {"abbe": 30 if i % 2 else 0}},
    "transform": lambda i: {"object": {"scale": 0.8 if i % 2 else 0.85}},
    "image": lambda i: {"image": {"width": 96 if i % 2 else 128, "height": 96 if i % 2 else 128}},
}
# The mix of a soak: mostly interactive-style edits, every kind at least once per round.
DEFAULT_MIX = ["camera", "camera", "light", "camera", "photons", "ior", "camera", "light", "extinction",
               "scattering", "phase", "abbe", "abbe", "transform", "image", "image"]

SCENE = {"image": {"width": 128, "height": 128}, "photons": {"count": 16384}, "volume": {"resolution": 48}}


def proc_sample(pid):
    """RSS (KiB), peak RSS (KiB), threads, open files and executable mappings of process `pid`."""
    status = {}
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            key, _, value = line.partition(":")
            status[key] = value.strip()
    with open(f"/proc/{pid}/maps") as f:
        exec_maps = sum(1 for line in f if "x" in line.split()[1])
    return {
        "rss_kib": int(status["VmRSS"].split()[0]),
        "hwm_kib": int(status["VmHWM"].split()[0]),
        "threads": int(status["Threads"]),
        "fds": len(os.listdir(f"/proc/{pid}/fd")),
        "exec_maps": exec_maps,
    }


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def request(conn, method, path, body=None, content_type=None):
    headers = {"Content-Type": content_type} if content_type else {}
    conn.request(method, path, body=body, headers=headers)
    res = conn.getresponse()
    data = res.read()
    return res.status, data


def wait_ready(host, port, proc, timeout=60.0):
    deadline = time.time() + timeout
    while time.time() < deadline:
        if proc is not None and proc.poll() is not None:
            sys.exit(f"soak: refractd exited with {proc.returncode}")
        try:
            conn = http.client.HTTPConnection(host, port, timeout=5)
            status, _ = request(conn, "GET", "/api/health")
            conn.close()
            if status == 200:
                return
        except OSError:
            pass
        time.sleep(0.2)
    sys.exit("soak: refractd did not answer /api/health")


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--refractd", help="start this refractd binary (own data dir and port)")
    parser.add_argument("--daemon-log", help="with --refractd: write its standard error here")
    parser.add_argument("--url", help="drive a running daemon, e.g. http://127.0.0.1:8080 (needs --pid)")
    parser.add_argument("--pid", type=int, help="the running daemon's process id")
    parser.add_argument("--minutes", type=float, default=0.0, help="run this long")
    parser.add_argument("--frames", type=int, default=0, help="or this many frames")
    parser.add_argument("--edits", default=",".join(DEFAULT_MIX),
                        help="comma-separated edit kinds, cycled (%s)" % ", ".join(EDITS))
    parser.add_argument("--quality", default="still", choices=["still", "interactive", "both"],
                        help="quality of the frames; both alternates")
    parser.add_argument("--every", type=float, default=10.0, help="seconds between samples")
    parser.add_argument("--every-frames", type=int, default=0, help="and a sample every this many frames")
    parser.add_argument("--rate", type=float, default=0.0, help="frames per second at most (0: back to back)")
    parser.add_argument("--json", action="store_true", help="print the samples as JSON at the end")
    args = parser.parse_args()
    if not args.minutes and not args.frames:
        parser.error("give --minutes or --frames")
    mix = args.edits.split(",")
    for kind in mix:
        if kind not in EDITS:
            parser.error(f"unknown edit kind {kind!r}")

    proc, data_dir = None, None
    if args.refractd:
        data_dir = tempfile.TemporaryDirectory(prefix="refract-soak-")
        port = free_port()
        proc = subprocess.Popen([args.refractd, "--port", str(port), "--ws-port", str(free_port()),
                                 "--data-dir", data_dir.name], stdout=subprocess.DEVNULL,
                                stderr=open(args.daemon_log, "w") if args.daemon_log else subprocess.DEVNULL)
        host, pid = "127.0.0.1", proc.pid
    elif args.url and args.pid:
        parsed = urllib.parse.urlparse(args.url)
        host, port, pid = parsed.hostname, parsed.port or 80, args.pid
    else:
        parser.error("give --refractd, or --url and --pid")

    samples = []
    try:
        wait_ready(host, port, proc)
        conn = http.client.HTTPConnection(host, port, timeout=600)
        scene_id = f"soak-{os.getpid()}"
        status, body = request(conn, "POST", f"/api/scenes?id={scene_id}", json.dumps(SCENE), "application/json")
        if status != 201:
            sys.exit(f"soak: cannot create the scene: {status} {body[:200]!r}")
        start = time.time()
        frames, failures, next_sample = 0, 0, start
        uses = {}  # frames of each edit kind so far: its values alternate

        def sample():
            s = proc_sample(pid)
            s.update({"seconds": round(time.time() - start, 1), "frames": frames, "failures": failures})
            samples.append(s)
            print(f"{s['seconds']:8.1f} s {frames:6d} frames  RSS {s['rss_kib'] / 1024:8.1f} MiB  "
                  f"peak {s['hwm_kib'] / 1024:8.1f} MiB  fds {s['fds']:4d}  threads {s['threads']:3d}  "
                  f"exec maps {s['exec_maps']:4d}" + (f"  failures {failures}" if failures else ""), flush=True)

        while True:
            now = time.time()
            if (args.frames and frames >= args.frames) or (args.minutes and now - start >= 60 * args.minutes):
                break
            if now >= next_sample or (args.every_frames and frames % args.every_frames == 0):
                sample()
                while next_sample <= now:
                    next_sample += args.every
            quality = args.quality if args.quality != "both" else ("interactive" if frames % 2 else "still")
            kind = mix[frames % len(mix)]
            uses[kind] = uses.get(kind, 0) + 1
            patch = EDITS[kind](uses[kind])
            frame_start = time.time()
            status, body = request(conn, "POST", f"/api/scenes/{scene_id}/frame.png?quality={quality}",
                                   json.dumps(patch), "application/merge-patch+json")
            if status != 200:
                failures += 1
                print(f"soak: frame {frames} ({kind}) failed: {status} {body[:200]!r}",
                      file=sys.stderr)
            frames += 1
            if args.rate > 0:
                time.sleep(max(0.0, 1.0 / args.rate - (time.time() - frame_start)))
        sample()
        request(conn, "DELETE", f"/api/scenes/{scene_id}")
    finally:
        if proc is not None:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
        if data_dir is not None:
            data_dir.cleanup()
    if args.json:
        print(json.dumps(samples, indent=1))
    first, last = samples[0], samples[-1]
    print(f"soak: {last['frames']} frames in {last['seconds']:.0f} s; RSS {first['rss_kib'] / 1024:.1f} -> "
          f"{last['rss_kib'] / 1024:.1f} MiB, fds {first['fds']} -> {last['fds']}, threads {first['threads']} -> "
          f"{last['threads']}, exec maps {first['exec_maps']} -> {last['exec_maps']}")
    return 1 if last["failures"] else 0


if __name__ == "__main__":
    sys.exit(main())
