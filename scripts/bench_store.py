#!/usr/bin/env python3
"""Store benchmark client (not a test): PATCH round trips, PATCH throughput and frames/s against one
refractd or HAProxy. scripts/bench-store.sh starts the configurations and calls this for each.

Usage: bench_store.py HOST:PORT LABEL [SECONDS]     prints one JSON line
"""
import http.client
import json
import statistics
import sys
import threading
import time

address, label = sys.argv[1], sys.argv[2]
seconds = float(sys.argv[3]) if len(sys.argv) > 3 else 5.0
host, port = address.rsplit(":", 1)
SCENE = {"image": {"width": 128, "height": 128}, "volume": {"resolution": 48}, "photons": {"count": 4096}}
PATCH = {"Content-Type": "application/merge-patch+json"}


def connect():
    return http.client.HTTPConnection(host, int(port), timeout=120)


def request(conn, method, path, body=None, headers=None):
    conn.request(method, path, body=None if body is None else json.dumps(body), headers=headers or {})
    res = conn.getresponse()
    data = res.read()
    return res.status, data


def create(conn, scene_id):
    status, body = request(conn, "POST", f"/api/scenes?id={scene_id}", SCENE, {"Content-Type": "application/json"})
    if status not in (201, 409):
        raise SystemExit(f"cannot create {scene_id}: {status} {body[:200]}")


def round_trips(prefix, count=200):
    conn = connect()
    create(conn, f"{prefix}-rt")
    times = []
    for i in range(count):
        start = time.perf_counter()
        status, _ = request(conn, "PATCH", f"/api/scenes/{prefix}-rt", {"image": {"exposure": 0.5 + (i % 2) * 0.25}}, PATCH)
        times.append((time.perf_counter() - start) * 1e3)
        assert status == 200, status
    times.sort()
    return statistics.median(times), times[int(0.95 * len(times))]


def in_parallel(workers, body):
    """Runs body(worker, conn, deadline) -> count on `workers` threads for `seconds`; total per second."""
    counts = [0] * workers
    deadline = time.perf_counter() + seconds

    def run(w):
        counts[w] = body(w, connect(), deadline)

    threads = [threading.Thread(target=run, args=(w,)) for w in range(workers)]
    start = time.perf_counter()
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return sum(counts) / (time.perf_counter() - start)


def edits_per_second(prefix, workers=8):
    conn = connect()
    for w in range(workers):
        create(conn, f"{prefix}-e{w}")

    def body(w, c, deadline):
        n = 0
        while time.perf_counter() < deadline:
            status, _ = request(c, "PATCH", f"/api/scenes/{prefix}-e{w}", {"image": {"exposure": 0.5 + (n % 2) * 0.25}}, PATCH)
            assert status == 200, status
            n += 1
        return n

    return in_parallel(workers, body)


def frames_per_second(prefix, workers=6):
    conn = connect()
    for w in range(workers):
        create(conn, f"{prefix}-f{w}")
        status, _ = request(conn, "GET", f"/api/scenes/{prefix}-f{w}/frame.png")  # builds the scene once
        assert status == 200, status

    def body(w, c, deadline):
        n = 0
        while time.perf_counter() < deadline:
            x = 0.3 if n % 2 else -0.3
            status, _ = request(c, "POST", f"/api/scenes/{prefix}-f{w}/frame.png?quality=interactive",
                                {"camera": {"position": [x, 0.5, 5.0]}}, PATCH)
            assert status == 200, status
            n += 1
        return n

    return in_parallel(workers, body)


prefix = f"bench-{int(time.time())}"
median, p95 = round_trips(prefix)
result = {"label": label, "patch_round_trip_ms": {"median": round(median, 2), "p95": round(p95, 2)},
          "patches_per_s_8_clients": round(edits_per_second(prefix), 1),
          "frames_per_s_6_scenes": round(frames_per_second(prefix), 2)}
print(json.dumps(result))
