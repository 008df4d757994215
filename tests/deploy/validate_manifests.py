#!/usr/bin/env python3
"""Checks deploy/ without a cluster: every Kubernetes manifest parses and has what the API server needs,
the probes, the hashing key and the flags match what refractd really serves and accepts (read from its
sources), the Secret, ICD and NetworkPolicy wiring is consistent, and HAProxy accepts both configs.

Usage: validate_manifests.py SOURCE_DIR   (ctest: deploy_manifests)
"""
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import unittest

import yaml

SOURCE = os.path.abspath(sys.argv.pop(1) if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "../.."))
K8S = os.path.join(SOURCE, "deploy/k8s")


def read(path):
    with open(os.path.join(SOURCE, path), encoding="utf-8") as f:
        return f.read()


def documents(directory):
    """(file, document) for every YAML document of a kustomization directory."""
    found = []
    for name in sorted(os.listdir(directory)):
        if name.endswith(".yaml"):
            with open(os.path.join(directory, name), encoding="utf-8") as f:
                found += [(name, d) for d in yaml.safe_load_all(f) if d is not None]
    return found


def find(docs, kind, name):
    matches = [d for _, d in docs if d["kind"] == kind and d["metadata"]["name"] == name]
    assert len(matches) == 1, f"expected one {kind} {name}, found {len(matches)}"
    return matches[0]


def routing_lines(config):
    """The lines that decide where a request goes and when a server counts as up."""
    keys = ("balance ", "hash-type ", "option httpchk ", "http-check ", "option forwardfor")
    return [line.strip() for line in config.splitlines() if line.strip().startswith(keys)]


BASE = documents(os.path.join(K8S, "base"))
GPU_PATCH = yaml.safe_load(read("deploy/k8s/gpu/refractd-gpu.yaml"))
REFRACTD = find(BASE, "Deployment", "refractd")
CONTAINER = REFRACTD["spec"]["template"]["spec"]["containers"][0]
HAPROXY_K8S_CFG = find(BASE, "ConfigMap", "haproxy")["data"]["haproxy.cfg"]
HAPROXY_CFG = read("deploy/haproxy/haproxy.cfg")
API_SERVER = read("server/http/api_server.cpp")


class Manifests(unittest.TestCase):
    def test_every_document_has_what_the_api_server_requires(self):
        for directory in ("base", "gpu"):
            for name, doc in documents(os.path.join(K8S, directory)):
                where = f"{directory}/{name}"
                if doc.get("kind") == "Kustomization":
                    continue
                for field in ("apiVersion", "kind", "metadata"):
                    self.assertIn(field, doc, where)
                self.assertRegex(doc["metadata"]["name"], r"^[a-z0-9]([-a-z0-9]*[a-z0-9])?$", where)
                if doc["kind"] == "Deployment" and directory == "base":
                    spec = doc["spec"]
                    self.assertEqual(spec["selector"]["matchLabels"].items() - spec["template"]["metadata"]["labels"].items(),
                                     set(), f"{where}: the selector must match the pod labels")
                    for container in spec["template"]["spec"]["containers"]:
                        self.assertIn("image", container, where)

    def test_kustomizations_name_files_that_exist(self):
        for directory in ("base", "gpu"):
            kustomization = yaml.safe_load(read(f"deploy/k8s/{directory}/kustomization.yaml"))
            paths = kustomization.get("resources", []) + [p["path"] for p in kustomization.get("patches", [])]
            for generator in kustomization.get("configMapGenerator", []):
                paths += generator["files"]
            for path in paths:
                self.assertTrue(os.path.exists(os.path.join(K8S, directory, path)), f"{directory}: {path}")

    def test_probes_ask_the_daemons_health_route_on_its_http_port(self):
        self.assertIn('route("GET", "/api/health"', API_SERVER)
        ports = {p["name"]: p["containerPort"] for p in CONTAINER["ports"]}
        self.assertEqual(ports["http"], 8080)
        for probe in ("readinessProbe", "livenessProbe"):
            self.assertEqual(CONTAINER[probe]["httpGet"], {"path": "/api/health", "port": "http"}, probe)
        self.assertIn("option httpchk GET /api/health", HAPROXY_K8S_CFG)

    def test_haproxy_hashes_on_the_scene_id_of_every_scene_route(self):
        # field(4,/) of "/api/scenes/ID/..." is ID: "", "api", "scenes", ID.
        self.assertEqual("/api/scenes/some-id/frame.png".split("/")[3], "some-id")
        self.assertIn("balance hash path,field(4,/)", routing_lines(HAPROXY_CFG))
        self.assertIn("hash-type consistent", routing_lines(HAPROXY_CFG))
        # refractd tells browsers behind a proxy to upgrade through the proxy's port (X-Forwarded-For).
        self.assertIn("option forwardfor", routing_lines(HAPROXY_CFG))
        self.assertIn('req.has_header("X-Forwarded-For")', API_SERVER)
        scene_routes = re.findall(r'route(?:_authorized)?\("[A-Z]+", R"\((/api/scenes/[^"]*)\)"', API_SERVER)
        self.assertGreater(len(scene_routes), 3)
        for route in scene_routes:
            self.assertTrue(route.startswith("/api/scenes/([^/]+)"), route)
        # The WebSocket endpoint: the same prefix, so upgrades hash the same way.
        self.assertIn('prefix = "/api/scenes/"', read("server/http/ws_server.cpp"))
        self.assertEqual(routing_lines(HAPROXY_K8S_CFG), routing_lines(HAPROXY_CFG),
                         "the Kubernetes HAProxy config must route exactly as deploy/haproxy/haproxy.cfg")

    def test_every_flag_given_to_refractd_is_one_it_accepts(self):
        accepted = set(re.findall(r'flag == "(--[a-z-]+)"', read("server/http/daemon_config.cpp")))
        self.assertIn("--store", accepted)
        for args in (CONTAINER["args"], GPU_PATCH["spec"]["template"]["spec"]["containers"][0]["args"]):
            for arg in args:
                self.assertIn(arg.split("=")[0], accepted, arg)

    def test_the_token_and_the_store_url_come_from_secrets(self):
        mounts = {m["name"]: m["mountPath"] for m in CONTAINER["volumeMounts"]}
        volumes = {v["name"]: v for v in REFRACTD["spec"]["template"]["spec"]["volumes"]}
        token_arg = [a for a in CONTAINER["args"] if a.startswith("--token-file=")]
        self.assertEqual(len(token_arg), 1)
        token_dir = os.path.dirname(token_arg[0].split("=", 1)[1])
        secret_mounts = [n for n, path in mounts.items() if path == token_dir and "secret" in volumes[n]]
        self.assertEqual(len(secret_mounts), 1, "the token file must lie in a mounted Secret")
        self.assertNotIn("--token=", " ".join(CONTAINER["args"]), "a token in args is readable in the pod spec")
        env = {e["name"]: e for e in CONTAINER["env"]}
        self.assertIn("--store=$(REFRACT_STORE)", CONTAINER["args"])
        secret = env["REFRACT_STORE"]["valueFrom"]["secretKeyRef"]
        cluster = find(BASE, "Cluster", "refract-db")
        self.assertEqual(secret, {"name": cluster["metadata"]["name"] + "-app", "key": "uri"},
                         "CloudNativePG names the application Secret <cluster>-app, with the URL under 'uri'")

    def test_the_gpu_variant_requests_a_gpu_and_loads_the_egl_driver(self):
        container = GPU_PATCH["spec"]["template"]["spec"]["containers"][0]
        for side in ("requests", "limits"):
            self.assertEqual(container["resources"][side]["nvidia.com/gpu"], 1, side)
        env = {e["name"]: e["value"] for e in container["env"]}
        self.assertIn("graphics", env["NVIDIA_DRIVER_CAPABILITIES"])
        mount = {m["name"]: m["mountPath"] for m in container["volumeMounts"]}["nvidia-icd"]
        self.assertEqual(env["VK_ICD_FILENAMES"], mount + "/nvidia_icd.json")
        icd = json.loads(read("deploy/k8s/gpu/nvidia_icd.json"))
        self.assertEqual(os.path.basename(icd["ICD"]["library_path"]), "libEGL_nvidia.so.0")
        # The patch replaces the args list: it must keep the store and the token.
        self.assertIn("--store=$(REFRACT_STORE)", container["args"])
        self.assertTrue(any(a.startswith("--token-file=") for a in container["args"]))

    def test_network_policies_admit_the_pods_that_need_in(self):
        haproxy_labels = find(BASE, "Deployment", "haproxy")["spec"]["template"]["metadata"]["labels"]
        policy = find(BASE, "NetworkPolicy", "refractd-from-haproxy")["spec"]
        self.assertEqual(policy["podSelector"]["matchLabels"], REFRACTD["spec"]["template"]["metadata"]["labels"])
        self.assertEqual(policy["ingress"][0]["from"][0]["podSelector"]["matchLabels"], haproxy_labels)
        self.assertEqual(policy["ingress"][0]["ports"][0]["port"], 8080)
        db_policy = find(BASE, "NetworkPolicy", "postgres-from-refractd")["spec"]
        self.assertIn({"podSelector": {"matchLabels": REFRACTD["spec"]["template"]["metadata"]["labels"]}},
                      db_policy["ingress"][0]["from"])
        for service in ("refractd", "refract"):
            selector = find(BASE, "Service", service)["spec"]["selector"]
            self.assertTrue(any(selector.items() <= d["spec"]["template"]["metadata"]["labels"].items()
                                for _, d in BASE if d["kind"] == "Deployment"), service)

    def test_haproxy_accepts_both_configs(self):
        env = dict(os.environ, REFRACT_LISTEN="127.0.0.1:8000", REFRACT_REPLICA_1="127.0.0.1:8081",
                   REFRACT_REPLICA_2="127.0.0.1:8082", REFRACT_REPLICA_3="127.0.0.1:8083")
        with tempfile.NamedTemporaryFile("w", suffix=".cfg") as k8s_cfg:
            k8s_cfg.write(HAPROXY_K8S_CFG)
            k8s_cfg.flush()
            for config in (os.path.join(SOURCE, "deploy/haproxy/haproxy.cfg"), k8s_cfg.name):
                # Debian puts it in /usr/sbin, which a non-root PATH may lack.
                haproxy = shutil.which("haproxy") or "/usr/sbin/haproxy"
                check = subprocess.run([haproxy, "-c", "-f", config], env=env, capture_output=True, text=True)
                self.assertEqual(check.returncode, 0, check.stdout + check.stderr)


class ContainerImage(unittest.TestCase):
    """What docker/Dockerfile promises, read from the file (scripts/container.sh builds and runs it)."""

    DOCKERFILE = read("docker/Dockerfile")

    def instruction(self, name):
        return [line for line in self.DOCKERFILE.splitlines() if line.startswith(name + " ")]

    def test_two_stages_the_last_one_unprivileged(self):
        self.assertEqual(len(self.instruction("FROM")), 2)
        users = self.instruction("USER")
        self.assertEqual(len(users), 1)
        self.assertNotIn(users[0].split()[1], ("root", "0"))
        self.assertGreater(self.DOCKERFILE.index("USER "), self.DOCKERFILE.rindex("FROM "))

    def test_health_check_and_entrypoint_use_what_the_daemon_serves_and_accepts(self):
        self.assertIn("http://127.0.0.1:8080/api/health", self.instruction("HEALTHCHECK")[0])
        start = self.DOCKERFILE.index("ENTRYPOINT ")
        entrypoint = json.loads(self.DOCKERFILE[start + len("ENTRYPOINT "):].replace("\\\n", ""))
        self.assertEqual(entrypoint[0], "refractd")
        accepted = set(re.findall(r'flag == "(--[a-z-]+)"', read("server/http/daemon_config.cpp")))
        for arg in entrypoint[1:]:
            if arg.startswith("--"):
                self.assertIn(arg, accepted)
        # Beyond loopback without a token the daemon refuses to start (tests/daemon_test.cpp): the image
        # bakes no token in and no --open.
        self.assertEqual(entrypoint[entrypoint.index("--bind") + 1], "0.0.0.0")
        self.assertNotIn("--open", entrypoint)
        self.assertFalse(any(a.startswith("--token") for a in entrypoint))


if __name__ == "__main__":
    unittest.main(verbosity=2)
