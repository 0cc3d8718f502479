#!/usr/bin/env python3
"""Relief's capacity model (docs/scaling.md), from the measured load runs in docs/load/.

For each workload it takes the largest stage of its committed sweep that held p99 latency within
50 ms, and from it the per-session costs: server cores, resident memory, bandwidth, and the cost
of a session's first delta (what a resume costs the replica it lands on). Then:

- the replicas needed for --sessions concurrent sessions of each workload, on replicas of
  --cores cores, --memory-gib GiB (80 % used) and --nic-gbit Gbit/s (70 % used), each run at
  --target-cpu of its cores, whichever binds first, plus one spare so
  that losing a replica leaves enough (N + 1);
- a replay of one replica failing under that load: its sessions reconnect, each after a gap drawn
  from the scale-out drill's measured reconnect gaps, to the replica with the fewest sessions
  (HAProxy's leastconn), and each resume costs its first-delta CPU there. It reports the reconnect
  storm's peak CPU demand per surviving replica (over 100 ms windows) and how long the backlog
  takes to clear.

Standard library only. Usage: python3 deploy/capacity.py [--sessions N] [--cores C] ...
"""

import argparse
import glob
import json
import math
import os
import random

HERE = os.path.dirname(os.path.abspath(__file__))
LOAD = os.path.join(HERE, "..", "docs", "load")

# The scale-out drill's reconnect gaps (tests/tests/e2e/scale_out.rs, 200 sessions through HAProxy:
# one replica of three killed, then a rolling restart), milliseconds: p50 and p99.
GAP_P50_MS, GAP_P99_MS = 23.0, 55.0


def workloads(knee_ms):
    """Per-session costs of every committed stream sweep."""
    out = []
    for path in sorted(glob.glob(os.path.join(LOAD, "*", "report.json"))):
        stages = json.load(open(path))["stages"]
        held = [s for s in stages if s["latency_ms"]["p99"] <= knee_ms and s["errors"] == 0]
        if not held or stages[0]["stream"].startswith("query"):
            continue
        s = max(held, key=lambda s: s["sessions"])
        n = s["sessions"]
        out.append({
            "name": os.path.basename(os.path.dirname(path)),
            "stream": s["stream"],
            "stage_sessions": n,
            "cores": s["server"]["cpu_utilisation"] / n,
            "rss": s["server"]["rss_per_session_bytes"],
            "bytes_s": s["session_bytes_per_s"]["mean"],
            # A first delta builds the whole cut: its latency at an unsaturated stage is its
            # computation (an upper bound on its CPU).
            "resume_s": s["first_latency_ms"]["mean"] / 1e3,
        })
    return out


def gap_s(rng):
    """A reconnect gap: log-normal through the drill's p50 and p99."""
    mu = math.log(GAP_P50_MS)
    sigma = (math.log(GAP_P99_MS) - mu) / 2.326
    return rng.lognormvariate(mu, sigma) / 1e3


def storm(w, replicas, sessions, cores, rng):
    """One replica of `replicas` fails under `sessions`; the survivors' peak CPU demand."""
    per = [sessions // replicas + (1 if i < sessions % replicas else 0) for i in range(replicas)]
    moved = per.pop(0)
    arrivals = sorted(gap_s(rng) for _ in range(moved))
    window = 0.1
    bins = {}
    for t in arrivals:
        k = min(range(len(per)), key=lambda i: per[i])
        per[k] += 1
        b = bins.setdefault((k, int(t / window)), 0.0)
        bins[(k, int(t / window))] = b + w["resume_s"]
    steady = max(per) * w["cores"]
    peak_resume = max(bins.values()) / window if bins else 0.0
    # The backlog on the busiest survivor: resume work it must do beyond its spare cores.
    spare = max(cores - max(per) * w["cores"], 1e-9)
    busiest = max(range(len(per)), key=lambda k: sum(v for (i, _), v in bins.items() if i == k))
    work = sum(v for (i, _), v in bins.items() if i == busiest)
    clear_s = max(arrivals[-1] if arrivals else 0.0, work / spare)
    return moved, steady, steady + peak_resume, clear_s


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sessions", type=int, default=100_000, help="concurrent sessions")
    ap.add_argument("--cores", type=float, default=8.0, help="cores per replica")
    ap.add_argument("--memory-gib", type=float, default=16.0, help="memory per replica, GiB")
    ap.add_argument("--nic-gbit", type=float, default=10.0, help="network per replica, Gbit/s")
    ap.add_argument("--target-cpu", type=float, default=0.6, help="share of cores in use")
    ap.add_argument("--knee-ms", type=float, default=50.0, help="p99 a stage must hold")
    ap.add_argument("--seed", type=int, default=17)
    a = ap.parse_args()
    if min(a.sessions, a.cores, a.memory_gib, a.nic_gbit) <= 0 or not 0 < a.target_cpu <= 1:
        ap.error("--sessions, --cores, --memory-gib and --nic-gbit must be positive, "
                 "--target-cpu in (0, 1]")
    rng = random.Random(a.seed)
    print(f"{a.sessions} sessions on replicas of {a.cores:g} cores, {a.memory_gib:g} GiB and "
          f"{a.nic_gbit:g} Gbit/s (70 % used), "
          f"run at {100 * a.target_cpu:.0f} % CPU; one replica lost under full load.\n")
    print("| workload (measured at) | cores/session | RSS/session | KiB/s/session | sessions/replica | replicas (N+1) | egress/replica | storm: sessions moved | busiest survivor: steady / peak cores | backlog clears in |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for w in workloads(a.knee_ms):
        by_cpu = a.target_cpu * a.cores / w["cores"]
        by_mem = a.memory_gib * 2**30 * 0.8 / w["rss"]
        by_net = 0.7 * a.nic_gbit * 1e9 / 8 / w["bytes_s"]
        limits = {"CPU": by_cpu, "memory": by_mem, "network": by_net}
        limit = min(limits, key=limits.get)
        per = int(limits[limit])
        n = math.ceil(a.sessions / per) + 1
        moved, steady, peak, clear = storm(w, n, a.sessions, a.cores, rng)
        print(f"| {w['name']}: {w['stream']} ({w['stage_sessions']}) | {w['cores']:.5f} | "
              f"{w['rss'] / 1024:.0f} KiB | {w['bytes_s'] / 1024:.1f} | {per} "
              f"({limit}) | {n} | "
              f"{per * w['bytes_s'] * 8 / 1e6:.0f} Mbit/s | {moved} | {steady:.2f} / {peak:.2f} | "
              f"{clear:.2f} s |")


if __name__ == "__main__":
    main()
