"""Pairs a second of hnnstereo.batch on local Dask clusters of 1 and 2 workers against a plain loop
over hnnstereo.match in this process, on the same pairs, taking turns within one run (so that
other load on the machine falls on each about equally); and the scheduler's overhead per task.

    python perf/batch_throughput.py --teddy-crops 100 teddy     # writes teddy/pairs.csv
    python perf/batch_throughput.py --pairs cell/pairs.csv --pairs teddy/pairs.csv --out /tmp/bt

Each measurement: every pair read, matched and its matches.csv and report.json written; the
Matchers are built before the clock starts (a warm-up pair per worker). Prints one line per
measurement and a summary per PAIRS.csv (medians): pairs a second, CPU seconds a pair and the
cores used (this process for the loop, the workers' processes for a cluster, PoCL's threads
included), how busy the whole machine was (/proc/stat: other users' load too), and the loop's
stages (read, match, write); --json writes them all. The loop runs with this process's
environment: `POCL_MAX_PTHREAD_COUNT=1 python perf/batch_throughput.py ...` limits it (and, with
2:POCL_MAX_PTHREAD_COUNT=1 in --workers, a cluster's workers) to one PoCL thread.
"""

import argparse
import json
import os
import shutil
import statistics
import sys
import time

import cv2
import distributed

import hnnstereo
import hnnstereo.batch as batch


def make_teddy_crops(n_pairs, folder, size=(400, 333)):
    """n_pairs rectified Teddy-size pairs: one 400x333 window of im2/im6 at n_pairs offsets."""
    teddy = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "data",
                         "middlebury2003_teddy")
    left = cv2.imread(os.path.join(teddy, "im2.png"), cv2.IMREAD_UNCHANGED)
    right = cv2.imread(os.path.join(teddy, "im6.png"), cv2.IMREAD_UNCHANGED)
    width, height = size
    os.makedirs(folder, exist_ok=True)
    rows = ["id,left,right,max_disparity"]
    for index in range(n_pairs):
        x0 = (index * 7) % (left.shape[1] - width + 1)
        y0 = (index * 5) % (left.shape[0] - height + 1)
        for side, image in (("l", left), ("r", right)):
            cv2.imwrite(os.path.join(folder, f"t{index:03d}_{side}.png"),
                        image[y0:y0 + height, x0:x0 + width])
        rows.append(f"t{index:03d},t{index:03d}_l.png,t{index:03d}_r.png,64")
    with open(os.path.join(folder, "pairs.csv"), "w") as f:
        f.write("\n".join(rows) + "\n")


def plain_loop(pairs, out_dir, stages=None):
    """One process: read, hnnstereo.match, write the two files -> seconds; `stages` (a dict)
    gets the seconds of each stage summed (read, match, write)."""
    stages = {} if stages is None else stages
    for stage in ("read", "match", "write"):
        stages.setdefault(stage, 0.0)
    start = time.perf_counter()
    for pair in pairs:
        t0 = time.perf_counter()
        left = cv2.imread(pair.left, cv2.IMREAD_UNCHANGED)
        right = cv2.imread(pair.right, cv2.IMREAD_UNCHANGED)
        t1 = time.perf_counter()
        result = hnnstereo.match(left, right, max_disparity=pair.max_disparity or 64,
                                 calib=pair.calib)
        t2 = time.perf_counter()
        folder = os.path.join(out_dir, pair.id)
        os.makedirs(folder, exist_ok=True)
        with open(os.path.join(folder, "matches.csv"), "w") as f:
            f.write(batch.matches_csv(result.matches))
        with open(os.path.join(folder, "report.json"), "w") as f:
            json.dump(result.report, f, separators=(",", ":"))  # as hnnstereo.batch writes it
        t3 = time.perf_counter()
        stages["read"] += t1 - t0
        stages["match"] += t2 - t1
        stages["write"] += t3 - t2
    return time.perf_counter() - start


def cpu_seconds():
    """This process's CPU seconds (user + system, all its threads: PoCL's too)."""
    times = os.times()
    return times.user + times.system


def machine_busy():
    """(busy, total) jiffies of the whole machine since boot (/proc/stat): every process, the
    other users' builds included."""
    with open("/proc/stat") as f:
        values = [int(v) for v in f.readline().split()[1:]]
    idle = values[3] + values[4]  # idle + iowait
    return sum(values) - idle, sum(values)


def on_cluster(client, pairs, out_dir):
    """match_pairs on the cluster -> (seconds, summed task seconds, the workers' CPU seconds)."""
    cpu_before = sum(client.run(cpu_seconds).values())
    start = time.perf_counter()
    report = batch.match_pairs(pairs, out_dir, client)
    seconds = time.perf_counter() - start
    cpu = sum(client.run(cpu_seconds).values()) - cpu_before
    assert report.done == len(pairs), report.brief()
    return seconds, sum(row["seconds"] for row in report.rows), cpu


def noop(index):
    return index


def task_overhead(client, n_tasks=2000):
    """Seconds a task of no work costs end to end (submit, schedule, run, gather), amortised."""
    start = time.perf_counter()
    futures = client.map(noop, range(n_tasks), pure=False)
    client.gather(futures)
    return (time.perf_counter() - start) / n_tasks


def cluster_name(spec):
    n_workers, _, variable = spec.partition(":")
    return f"{n_workers} workers" + (f" {variable}" if variable else "")


def start_cluster(spec):
    """spec: "N" workers, or "N:NAME=VALUE" with an environment variable for the workers."""
    n_workers, _, variable = spec.partition(":")
    env = dict([variable.split("=", 1)]) if variable else None
    start = time.perf_counter()
    cluster = distributed.LocalCluster(n_workers=int(n_workers), threads_per_worker=1, env=env,
                                       processes=True,
                                       dashboard_address=None, silence_logs=40,
                                       scheduler_kwargs={"dashboard_address": ":0"})
    client = distributed.Client(cluster)
    return cluster, client, time.perf_counter() - start


def measure(pairs_csv, clusters, out_root, repeats, log):
    pairs = batch.read_pairs(pairs_csv)
    warm = pairs[:4]
    plain_loop(warm[:1], os.path.join(out_root, "warm-loop"))
    for index, (_, client, _) in enumerate(clusters.values()):
        batch.match_pairs(warm, os.path.join(out_root, f"warm-{index}"), client)
    runs = []
    for repeat in range(repeats):
        for name in ["loop"] + list(clusters):
            out_dir = os.path.join(out_root, "run")
            shutil.rmtree(out_dir, ignore_errors=True)
            task_seconds, stages = None, {}
            busy_before = machine_busy()
            if name == "loop":
                cpu_before = cpu_seconds()
                seconds = plain_loop(pairs, out_dir, stages)
                cpu = cpu_seconds() - cpu_before
            else:
                seconds, task_seconds, cpu = on_cluster(clusters[name][1], pairs, out_dir)
            busy_after = machine_busy()
            machine = (busy_after[0] - busy_before[0]) / max(1, busy_after[1] - busy_before[1])
            run = {"pairs_csv": pairs_csv, "config": name, "repeat": repeat, "pairs": len(pairs),
                   "seconds": seconds, "pairs_per_second": len(pairs) / seconds,
                   "task_seconds": task_seconds, "load1": os.getloadavg()[0],
                   "cpu_s_per_pair": cpu / len(pairs), "cores_used": cpu / seconds,
                   "machine_busy": machine,
                   "stages_ms_per_pair": {k: 1e3 * v / len(pairs) for k, v in stages.items()}}
            runs.append(run)
            stage_text = " ".join(f"{k} {v:.0f}" for k, v in run["stages_ms_per_pair"].items())
            print(f"{os.path.basename(os.path.dirname(pairs_csv))} {name}: {len(pairs)} pairs "
                  f"in {seconds:.1f} s = {run['pairs_per_second']:.2f} pairs/s; "
                  f"{1e3 * run['cpu_s_per_pair']:.0f} ms CPU a pair, {run['cores_used']:.2f} cores "
                  f"used, machine {100 * machine:.0f} % busy (load {run['load1']:.1f})"
                  + (f"; ms a pair: {stage_text}" if stage_text else ""), file=log, flush=True)
    return runs


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--teddy-crops", nargs=2, metavar=("N", "DIR"),
                        help="only write N Teddy-size pairs and DIR/pairs.csv")
    parser.add_argument("--pairs", action="append", help="a PAIRS.csv (repeatable)")
    parser.add_argument("--out", help="scratch folder for the results")
    parser.add_argument("--repeats", type=int, default=2, help="turns of each configuration")
    parser.add_argument("--workers", default="1,2",
                        help="clusters, comma-separated: N workers, or N:NAME=VALUE with an "
                             "environment variable for its workers (2:POCL_MAX_PTHREAD_COUNT=1)")
    parser.add_argument("--json", help="write every measurement here")
    args = parser.parse_args()
    if args.teddy_crops:
        return make_teddy_crops(int(args.teddy_crops[0]), args.teddy_crops[1])
    if not args.pairs or not args.out:
        parser.error("--pairs and --out are needed")

    clusters = {cluster_name(spec): start_cluster(spec) for spec in args.workers.split(",")}
    for name, (_, _, seconds) in clusters.items():
        print(f"cluster of {name} started in {seconds:.1f} s", flush=True)
    overhead = task_overhead(list(clusters.values())[-1][1])
    print(f"scheduler: {overhead * 1e3:.2f} ms a task of no work ({list(clusters)[-1]})")
    runs = []
    try:
        for pairs_csv in args.pairs:
            runs += measure(os.path.abspath(pairs_csv), clusters, args.out, args.repeats,
                            sys.stdout)
    finally:
        for cluster, client, _ in clusters.values():
            client.close()
            cluster.close()
    for pairs_csv in args.pairs:
        mine = [r for r in runs if r["pairs_csv"] == os.path.abspath(pairs_csv)]
        loop = statistics.median(r["pairs_per_second"] for r in mine if r["config"] == "loop")
        for config in sorted({r["config"] for r in mine}):
            chosen = [r for r in mine if r["config"] == config]
            rate = statistics.median(r["pairs_per_second"] for r in chosen)
            cpu = statistics.median(r["cpu_s_per_pair"] for r in chosen)
            cores = statistics.median(r["cores_used"] for r in chosen)
            busy = statistics.median(r["machine_busy"] for r in chosen)
            print(f"{pairs_csv}: {config}: median {rate:.2f} pairs/s = {rate / loop:.2f} x loop; "
                  f"{1e3 * cpu:.0f} ms CPU a pair, {cores:.2f} cores used, machine "
                  f"{100 * busy:.0f} % busy")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"task_overhead_s": overhead, "runs": runs,
                       "cluster_start_s": {n: c[2] for n, c in clusters.items()}}, f, indent=2)


if __name__ == "__main__":
    main()
