#!/usr/bin/env python3
"""Daemon frame benchmark (not a test): two refractd binaries compared interleaved on one machine, on the
default scene (the one a first start creates), through HTTP as a client sees them. Each round starts
each binary in turn on a fresh data directory, warms it with one frame, then times, per case, `count`
frames each of a new revision:
  still      POST frame.png (level 1) with a light edit: photons, view and tone map rerun
  camera     POST frame.png with a camera edit: view and tone map
  interactive  POST frame.png?quality=interactive with a light edit (the budget's size and photons)
  edit       PATCH alone (no frame): the store's round trip
Prints one line per (round, binary, case) and the medians over rounds, as JSON.

Usage: bench_daemon.py OLD_REFRACTD NEW_REFRACTD [ROUNDS=3] [COUNT=8]
"""
import http.client
import json
import os
import shutil
import socket
import statistics
import subprocess
import sys
import tempfile
import time

binaries = {"old": sys.argv[1], "new": sys.argv[2]}
rounds = int(sys.argv[3]) if len(sys.argv) > 3 else 3
count = int(sys.argv[4]) if len(sys.argv) > 4 else 8
PATCH = {"Content-Type": "application/merge-patch+json"}


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def request(port, method, path, body=None, headers=None):
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=120)
    conn.request(method, path, body=None if body is None else json.dumps(body), headers=headers or {})
    res = conn.getresponse()
    data = res.read()
    conn.close()
    if res.status not in (200, 201):
        raise SystemExit(f"{method} {path}: {res.status} {data[:200]}")
    return data


def timed(port, method, path, body, headers=PATCH):
    start = time.perf_counter()
    request(port, method, path, body, headers)
    return (time.perf_counter() - start) * 1000.0


def measure(binary):
    data = tempfile.mkdtemp(prefix="refract-bench-")
    port, ws_port = free_port(), free_port()
    env = dict(os.environ, LP_NUM_THREADS=os.environ.get("LP_NUM_THREADS", "2"))
    daemon = subprocess.Popen([binary, "--data-dir", data, "--port", str(port), "--ws-port", str(ws_port)],
                              stderr=subprocess.DEVNULL, env=env)
    try:
        for _ in range(300):
            try:
                request(port, "GET", "/api/health")
                break
            except (OSError, SystemExit):
                time.sleep(0.1)
        scene = "/api/scenes/default"
        request(port, "GET", scene + "/frame.png")  # warm: volume, photons, pipelines
        request(port, "GET", scene + "/frame.png?quality=interactive")
        cases = {}
        cases["still"] = [timed(port, "POST", scene + "/frame.png", {"light": {"intensity": 40 + i}})
                          for i in range(count)]
        cases["camera"] = [timed(port, "POST", scene + "/frame.png",
                                 {"camera": {"position": [2.2 + 0.01 * (i + 1), 2.0, 5.0]}}) for i in range(count)]
        cases["interactive"] = [timed(port, "POST", scene + "/frame.png?quality=interactive",
                                      {"light": {"intensity": 60 + i}}) for i in range(count)]
        cases["edit"] = [timed(port, "PATCH", scene, {"image": {"exposure": 1.0 + 0.01 * (i + 1)}})
                         for i in range(count)]
        return {case: statistics.median(ms) for case, ms in cases.items()}
    finally:
        daemon.terminate()
        daemon.wait(timeout=30)
        shutil.rmtree(data, ignore_errors=True)


results = {name: {} for name in binaries}
for r in range(rounds):
    for name, binary in binaries.items():
        medians = measure(binary)
        for case, ms in medians.items():
            results[name].setdefault(case, []).append(ms)
            print(json.dumps({"round": r, "binary": name, "case": case, "median_ms": round(ms, 1)}), flush=True)
summary = {case: {name: round(statistics.median(results[name][case]), 1) for name in binaries}
           for case in results["old"]}
for case, figures in summary.items():
    figures["new/old"] = round(figures["new"] / figures["old"], 3)
print(json.dumps({"summary": summary}))
