#!/usr/bin/env python3
"""Checks deploy/k8s without a Kubernetes cluster: every manifest parses, the StatefulSets
mount what they name, the ConfigMap's template and render script say what the checked copies
(member.toml.in, render-config.sh) say, and the configuration rendered for a pod is one sculptd
accepts (`sculptd serve --check`, which opens no scene, port or etcd connection).

usage: k8s_manifests_test.py --sculptd BUILD/bin/sculptd [--k8s deploy/k8s]
"""
import argparse
import os
import subprocess
import sys
import tempfile
import tomllib

import yaml

failures = []


def check(cond, what):
    print(("ok   " if cond else "FAIL ") + what)
    if not cond:
        failures.append(what)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sculptd", required=True)
    ap.add_argument("--k8s", default=os.path.join(os.path.dirname(__file__), "../../deploy/k8s"))
    a = ap.parse_args()

    docs = {}
    for name in sorted(os.listdir(a.k8s)):
        if name.endswith(".yaml"):
            with open(os.path.join(a.k8s, name)) as f:
                parsed = [d for d in yaml.safe_load_all(f) if d is not None]
            check(all("kind" in d and "apiVersion" in d for d in parsed),
                  f"{name}: {len(parsed)} documents, each with kind and apiVersion")
            for d in parsed:
                docs[(d["kind"], d["metadata"]["name"])] = d
    for key in [("StatefulSet", "etcd"), ("Service", "etcd"), ("StatefulSet", "sculptd"),
                ("Service", "sculptd"), ("ConfigMap", "sculptd-config")]:
        check(key in docs, f"{key[0]} {key[1]} is defined")
    if failures:
        return 1

    for sts_name in ["etcd", "sculptd"]:
        sts = docs[("StatefulSet", sts_name)]
        spec = sts["spec"]
        svc = docs[("Service", spec["serviceName"])]
        check(svc["spec"].get("clusterIP") == "None",
              f"{sts_name}: its serviceName {spec['serviceName']} is a headless service")
        labels = spec["template"]["metadata"]["labels"]
        check(all(labels.get(k) == v for k, v in spec["selector"]["matchLabels"].items()),
              f"{sts_name}: the selector matches the pod template's labels")
        pod = spec["template"]["spec"]
        volumes = {v["name"] for v in pod.get("volumes", [])}
        volumes |= {c["metadata"]["name"] for c in spec.get("volumeClaimTemplates", [])}
        for c in pod.get("initContainers", []) + pod["containers"]:
            for m in c.get("volumeMounts", []):
                check(m["name"] in volumes, f"{sts_name}/{c['name']}: volume {m['name']} exists")

    cm = docs[("ConfigMap", "sculptd-config")]["data"]
    with open(os.path.join(a.k8s, "member.toml.in"), "rb") as f:
        checked = tomllib.load(f)
    check(tomllib.loads(cm["member.toml.in"]) == checked,
          "the ConfigMap's member.toml.in has the same settings as deploy/k8s/member.toml.in")
    etcd_replicas = docs[("StatefulSet", "etcd")]["spec"]["replicas"]
    check(checked["cluster"]["etcd"] ==
          [f"http://etcd-{i}.etcd:2379" for i in range(etcd_replicas)],
          "cluster.etcd lists every etcd pod of etcd.yaml")

    sculptd = docs[("StatefulSet", "sculptd")]["spec"]["template"]["spec"]
    args = sculptd["containers"][0]["args"]
    env = {e["name"] for e in sculptd["containers"][0].get("env", [])}
    check("SCULPT_VIEWER_TOKEN" in env, "sculptd gets the viewer token from the environment")
    init = {e["name"]: e for e in sculptd["initContainers"][0].get("env", [])}
    peer_ref = init.get("SCULPT_PEER_TOKEN", {}).get("valueFrom", {}).get("secretKeyRef", {})
    check(peer_ref.get("name") == "sculpt-tokens" and peer_ref.get("key") == "peer",
          "the init container gets the peer token from the Secret sculpt-tokens (key peer)")

    with tempfile.TemporaryDirectory() as tmp:
        peer_token = "k8s-test-peer-token-0123456789abcdef"
        pod_env = dict(os.environ, POD_NAME="sculptd-1", POD_NAMESPACE="sculpt", SERVICE="sculptd",
                       SCULPT_PEER_TOKEN=peer_token)
        outs = {}
        # The checked script, and the ConfigMap's copy run as the init container runs it.
        rendered = os.path.join(tmp, "checked.toml")
        r = subprocess.run(["sh", os.path.join(a.k8s, "render-config.sh"),
                            os.path.join(a.k8s, "member.toml.in"), rendered],
                           env=pod_env, capture_output=True, text=True)
        check(r.returncode == 0, "render-config.sh renders the template: " + r.stderr.strip())
        check(peer_token not in r.stdout + r.stderr, "render-config.sh does not print the token")
        check(os.stat(rendered).st_mode & 0o077 == 0,
              "the rendered file (it holds the peer token) is readable by its owner only")
        no_peer = {k: v for k, v in pod_env.items() if k != "SCULPT_PEER_TOKEN"}
        r = subprocess.run(["sh", os.path.join(a.k8s, "render-config.sh"),
                            os.path.join(a.k8s, "member.toml.in"), os.path.join(tmp, "x.toml")],
                           env=no_peer, capture_output=True, text=True)
        check(r.returncode != 0 and "SCULPT_PEER_TOKEN" in r.stderr,
              "render-config.sh refuses to render without SCULPT_PEER_TOKEN")
        with open(rendered, "rb") as f:
            outs["checked"] = tomllib.load(f)
        tpl = os.path.join(tmp, "config-template")
        cfg = os.path.join(tmp, "config")
        os.makedirs(tpl)
        os.makedirs(cfg)
        for k, v in cm.items():
            with open(os.path.join(tpl, k), "w") as f:
                f.write(v)
        script = cm["render-config.sh"].replace("/config-template/", tpl + "/") \
                                       .replace("/config/", cfg + "/")
        r = subprocess.run(["sh", "-c", script], env=pod_env, capture_output=True, text=True)
        check(r.returncode == 0, "the ConfigMap's render script runs: " + r.stderr.strip())
        with open(os.path.join(cfg, "sculptd.toml"), "rb") as f:
            outs["configmap"] = tomllib.load(f)
        check(outs["checked"] == outs["configmap"], "both render scripts write the same settings")
        k = outs["checked"]["cluster"]
        host = "sculptd-1.sculptd.sculpt.svc.cluster.local"
        check(k["member"] == "sculptd-1" and k["advertise"] == host + ":7420" and
              k["advertise_http"] == host + ":7421",
              "the member is named after its pod and advertises its stable DNS name")
        check(k.get("peer_token") == peer_token,
              "cluster.peer_token is the one from SCULPT_PEER_TOKEN")

        # sculptd accepts the rendered file with the StatefulSet's own arguments.
        serve_args = [x.replace("/config/sculptd.toml", rendered) for x in args]
        check(serve_args[0] == "serve", "the container runs `sculptd serve`")
        r = subprocess.run([a.sculptd] + serve_args + ["--check"],
                           env=dict(os.environ, SCULPT_SCULPTOR_TOKEN="k8s-test-sculptor",
                                    SCULPT_VIEWER_TOKEN="k8s-test-viewer"),
                           capture_output=True, text=True)
        check(r.returncode == 0 and "cluster member sculptd-1" in r.stdout and
              "peer token set" in r.stdout,
              "sculptd serve --check accepts the rendered configuration: " +
              (r.stdout + r.stderr).strip())
        check(peer_token not in r.stdout + r.stderr, "sculptd serve --check does not print the token")

        # And the check is a real one: a rendering that lost the member name is refused.
        bad = os.path.join(tmp, "bad.toml")
        with open(rendered) as f, open(bad, "w") as g:
            g.write(f.read().replace('member = "sculptd-1"', 'member = "@MEMBER@"'))
        r = subprocess.run([a.sculptd, "serve", "--config", bad, "--check"],
                           env=dict(os.environ, SCULPT_SCULPTOR_TOKEN="k8s-test-sculptor",
                                    SCULPT_VIEWER_TOKEN="k8s-test-viewer"),
                           capture_output=True, text=True)
        check(r.returncode == 2 and "cluster.member" in r.stdout + r.stderr,
              "sculptd serve --check refuses an unrendered member name, naming cluster.member")

    print(f"{len(failures)} failure(s)")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
