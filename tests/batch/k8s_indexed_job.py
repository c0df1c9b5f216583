#!/usr/bin/env python3
"""The Kubernetes example (examples/jobs/k8s) without a cluster: its manifests checked, then each
Job's pods run here as the Job controller and the kubelet would start them.

usage: k8s_indexed_job.py --blockwalk BIN --volume DIR [--parallel P] [--env NAME=VALUE ...]

DIR stands for the PersistentVolumeClaim: it must hold the city where the plan Job's CITY points
(under the mount path, /data). --env sets an environment variable that a Job's container
declares (as `kubectl set env` would; e.g. MAX_BUILDINGS=100 for a small city in several tiles).

What a pod gets, as on a cluster:
- its container's `env`, each value with `$(VAR)` references to the variables before it
  expanded, then JOB_COMPLETION_INDEX (the pod's index, 0 .. completions - 1) appended by the
  Job controller to every container of an Indexed Job's pods;
- `command` and `args` with `$(VAR)` expanded from that environment (`$$` escapes a `$`, an
  unknown reference stays as written), run without a shell;
- the volume at its mount path: the mount path at the start of an argument is replaced by DIR.
The tiles Job's pods run `parallelism` at a time. The plan pod's output is counted the way
run.sh counts it, and the tiles Job is filled in by `run.sh render-tiles`.

Prints one JSON object: {"out": the plan's folder in DIR, "tiles": N, "pods": pods run}.
"""

import argparse
import concurrent.futures
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import yaml

K8S = Path(__file__).resolve().parents[2] / "examples/jobs/k8s"
MOUNT = "/data"
REF = re.compile(r"\$\$|\$\(([A-Za-z_][A-Za-z0-9_.-]*)\)")


class Fail(Exception):
    pass


def check(cond, what):
    if not cond:
        raise Fail(what)


def expand(text, env):
    """Kubernetes' `$(VAR)` expansion of a command, an argument or an env value."""

    def sub(m):
        if m.group(0) == "$$":
            return "$"
        name = m.group(1)
        return env[name] if name in env else m.group(0)

    return REF.sub(sub, str(text))


def load(name, text=None):
    doc = yaml.safe_load(text if text is not None else (K8S / name).read_text())
    check(isinstance(doc, dict), f"{name}: not one YAML object")
    return doc


def job_container(name, doc, pvc):
    """The checks every Job shares; returns the Job's only container."""
    check(doc.get("apiVersion") == "batch/v1", f"{name}: apiVersion {doc.get('apiVersion')!r}")
    check(doc.get("kind") == "Job", f"{name}: kind {doc.get('kind')!r}, not Job")
    pod = doc["spec"]["template"]["spec"]
    check(pod.get("restartPolicy") in ("Never", "OnFailure"), f"{name}: restartPolicy {pod.get('restartPolicy')!r}")
    (c,) = pod["containers"]
    check(c["command"] == ["blockwalk"], f"{name}: command {c['command']}")
    volumes = {v["name"]: v for v in pod["volumes"]}
    mounts = [m for m in c["volumeMounts"] if m["mountPath"] == MOUNT]
    check(len(mounts) == 1, f"{name}: no volume mounted at {MOUNT}")
    claim = volumes[mounts[0]["name"]].get("persistentVolumeClaim", {}).get("claimName")
    check(claim == pvc, f"{name}: the volume at {MOUNT} is claim {claim!r}, not {pvc!r}")
    check("limits" in c.get("resources", {}), f"{name}: no resource limits")
    return c


def pod_env(container, overrides, index=None):
    env = {}
    for e in container.get("env", []):
        env[e["name"]] = expand(overrides.get(e["name"], e["value"]), env)
    if index is not None:
        env["JOB_COMPLETION_INDEX"] = str(index)
    return env


def run_pod(name, container, overrides, args_, index=None):
    env = pod_env(container, overrides, index)
    argv = [expand(a, env) for a in container["command"] + container["args"]]
    argv = [args_.volume + a[len(MOUNT):] if a == MOUNT or a.startswith(MOUNT + "/") else a for a in argv]
    proc_env = dict(env, PATH=f"{Path(args_.blockwalk).parent}:/usr/bin:/bin", HOSTNAME=name)
    p = subprocess.run(argv, env=proc_env, capture_output=True, text=True)
    if p.returncode != 0:
        raise Fail(f"pod {name} ({' '.join(argv)}) exited {p.returncode}: {p.stderr.strip()}")
    return argv, p.stdout


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--blockwalk", required=True)
    ap.add_argument("--volume", required=True)
    ap.add_argument("--parallel", type=int, default=3)
    ap.add_argument("--env", action="append", default=[])
    args_ = ap.parse_args()
    args_.volume = str(Path(args_.volume).resolve())
    check(Path(args_.blockwalk).name == "blockwalk", "--blockwalk must be a binary named blockwalk")
    overrides = dict(kv.split("=", 1) for kv in args_.env)

    pvc = load("pvc.yaml")
    check(pvc["kind"] == "PersistentVolumeClaim", "pvc.yaml: not a PersistentVolumeClaim")
    check(pvc["spec"]["accessModes"] == ["ReadWriteMany"], "pvc.yaml: the tile pods share the volume: ReadWriteMany")
    claim = pvc["metadata"]["name"]

    plan_c = job_container("plan-job.yaml", load("plan-job.yaml"), claim)
    merge_c = job_container("merge-job.yaml", load("merge-job.yaml"), claim)
    raw = load("tiles-job.yaml")
    check(raw["spec"]["completions"] == "${TILES}", "tiles-job.yaml: completions is not the ${TILES} run.sh fills")
    check(raw["spec"]["parallelism"] == "${PARALLEL}", "tiles-job.yaml: parallelism is not ${PARALLEL}")
    for k in overrides:
        check(
            any(k in {e["name"] for e in c.get("env", [])} for c in (plan_c, merge_c)),
            f"--env {k}: no Job's container declares {k}",
        )
    check(plan_c["args"][:2] == ["jobs", "plan"], f"plan-job.yaml: args {plan_c['args']}")
    check(merge_c["args"][:2] == ["jobs", "merge"], f"merge-job.yaml: args {merge_c['args']}")

    # The plan Job's pod; its stdout holds one `jobs run` line per tile, as run.sh counts them.
    plan_argv, out = run_pod("blockwalk-plan-0", plan_c, overrides, args_)
    n = sum(1 for line in out.splitlines() if " jobs run " in line)
    out_dir = Path(plan_argv[plan_argv.index("-o") + 1])
    plan = json.loads((out_dir / "plan.json").read_text())
    check(n == len(plan["tiles"]), f"the plan pod printed {n} commands for {len(plan['tiles'])} tiles")

    # The tiles Job, filled in by run.sh.
    text = subprocess.run(
        ["bash", str(K8S / "run.sh"), "render-tiles", str(n), str(args_.parallel)],
        check=True, capture_output=True, text=True,
    ).stdout
    tiles = load("tiles-job.yaml (rendered)", text)
    tile_c = job_container("tiles-job.yaml", tiles, claim)
    spec = tiles["spec"]
    check(spec["completionMode"] == "Indexed", "tiles-job.yaml: completionMode is not Indexed")
    check(spec["completions"] == n and spec["parallelism"] == args_.parallel,
          f"rendered completions {spec['completions']!r}, parallelism {spec['parallelism']!r}")
    check(tile_c["args"][:2] == ["jobs", "run"] and "$(JOB_COMPLETION_INDEX)" in tile_c["args"],
          f"tiles-job.yaml: args {tile_c['args']}")

    def tile(i):
        argv, _ = run_pod(f"blockwalk-tiles-{i}", tile_c, overrides, args_, index=i)
        return argv

    with concurrent.futures.ThreadPoolExecutor(max_workers=spec["parallelism"]) as pool:
        argvs = list(pool.map(tile, range(spec["completions"])))
    for i, argv in enumerate(argvs):
        check(argv[argv.index("--tile") + 1] == str(i), f"pod {i} ran {argv}")
        check(Path(argv[3]) == out_dir / "plan.json", f"pod {i} read {argv[3]}, the plan is in {out_dir}")

    merge_argv, _ = run_pod("blockwalk-merge-0", merge_c, overrides, args_)
    check(Path(merge_argv[3]) == out_dir, f"the merge pod merges {merge_argv[3]}, the plan is in {out_dir}")
    print(json.dumps({"out": str(out_dir), "tiles": n, "pods": n + 2}))


if __name__ == "__main__":
    try:
        main()
    except Fail as e:
        print(f"k8s_indexed_job: {e}", file=sys.stderr)
        sys.exit(1)
