"""Experiment backends: 4 similar items one after another vs a local process pool vs Dask.

    python benchmarks/bench_experiments.py [--items 4] [--vertices 40000] [--max-iter 150]
                                           [--workers 2] [--repeat 1]

The items are the embedded synthetic face at ``--vertices`` vertices, identities 0..items-1
(same size, similar work), parameterized in converged mode with ``--max-iter`` SEM steps, no
figures. Each backend runs the whole experiment end to end as a user would — ``python -m
pipeline experiment`` in a fresh subprocess and a fresh output folder (nothing cached), so the
times include interpreter start, imports and spawning workers (and, for ``--scheduler local``,
starting the ``LocalCluster``):

* ``serial``: ``--workers 1``, the items one after another in one process with the default BLAS
  threads (the strict baseline: one interpreter start and one set of imports for all items);
* ``N × sem-pipeline run``: each item's own ``config.yaml`` run by ``python -m pipeline run`` in
  a fresh process, one after another (how the items run without the experiment runner; each
  pays interpreter start and imports);
* ``serial, 1 BLAS thread``: the same with ``OPENBLAS_NUM_THREADS=1`` (the per-item setting the
  pool uses);
* ``process pool``: ``--workers N`` (spawned workers, 1 BLAS thread each);
* ``Dask, running LocalCluster``: ``--scheduler tcp://…`` to a ``LocalCluster`` of N
  single-threaded worker processes started (untimed) just before, as an existing cluster;
* ``Dask, --scheduler local``: the CLI starts the ``LocalCluster`` itself (timed).

``ratio`` is the wall time over the ``serial`` one; ``item s`` the sum of the items' own wall
times (from their ``item.json``), which shows how much the cores were shared; ``other work``
the cores that other processes kept busy meanwhile (``/proc/stat`` minus this run's own CPU
time), since work beside the benchmark slows the parallel runs most. With ``--repeat`` each
backend runs that many times, interleaved, and the fastest run is shown.

The ratio of N workers stays above 1/N: items side by side share memory bandwidth (their
``item s`` sum exceeds the serial one), and each spawned worker pays interpreter start and
imports. The README's performance section gives the current figures.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[1]


def load() -> str:
    return " ".join(Path("/proc/loadavg").read_text().split()[:3]) if \
        Path("/proc/loadavg").exists() else "?"


def busy_seconds() -> float:
    """CPU seconds all processes of the machine have used so far (``/proc/stat``)."""
    fields = Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]
    user, nice, system, idle, iowait, irq, softirq, steal = map(int, fields[:8])
    return (user + nice + system + irq + softirq + steal) / os.sysconf("SC_CLK_TCK")


def our_cpu() -> dict:
    """CPU seconds of this process's reaped children (key None) and of each live descendant
    (the pre-started Dask cluster's processes)."""
    import psutil

    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    out = {None: r.ru_utime + r.ru_stime}
    for child in psutil.Process().children(recursive=True):
        try:
            t = child.cpu_times()
            out[child.pid] = t.user + t.system
        except psutil.Error:
            pass
    return out


@contextmanager
def dask_cluster(workers: int):
    """A LocalCluster started outside the timed run, as an already running cluster is."""
    import dask
    from distributed import LocalCluster

    with dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}):
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=None)
    try:
        yield cluster.scheduler_address
    finally:
        cluster.close()


def run(config: Path, out: Path, args: list[str], env: dict) -> tuple[float, float, float]:
    """Wall time, sum of the items' times, and the cores other work used meanwhile."""
    busy0, ours0 = busy_seconds(), our_cpu()
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "pipeline", "experiment", str(config),
                           "--out", str(out), *args], capture_output=True, text=True,
                          env=env, cwd=REPO)
    wall = time.perf_counter() - t0
    busy1, ours1 = busy_seconds(), our_cpu()
    ours = sum(v - ours0.get(k, 0.0) for k, v in ours1.items())
    others = max(0.0, busy1 - busy0 - ours) / wall
    if proc.returncode != 0:
        sys.exit(f"benchmark run {args} failed (exit {proc.returncode}):\n{proc.stderr}")
    items = sum(json.loads(p.read_text())["seconds"]["total"]
                for p in out.glob("*/*/item.json"))
    return wall, items, others


def run_one_by_one(config: Path, out: Path, env: dict) -> tuple[float, float, float]:
    """The items' single-run configs (written by a cached experiment run into ``config.yaml``
    of each item) run by ``python -m pipeline run``, one process after another."""
    prepared = out.parent / f"{out.name}_configs"
    subprocess.run([sys.executable, "-m", "pipeline", "experiment", str(config), "--out",
                    str(prepared), "--workers", "1"], capture_output=True, env=env, cwd=REPO,
                   check=True)
    configs = sorted(prepared.glob("*/*/config.yaml"))
    busy0, ours0 = busy_seconds(), our_cpu()
    t0 = time.perf_counter()
    for c in configs:
        subprocess.run([sys.executable, "-m", "pipeline", "run", str(c), "--out", str(out)],
                       capture_output=True, env=env, cwd=REPO, check=True)
    wall = time.perf_counter() - t0
    busy1, ours1 = busy_seconds(), our_cpu()
    ours = sum(v - ours0.get(k, 0.0) for k, v in ours1.items())
    return wall, float("nan"), max(0.0, busy1 - busy0 - ours) / wall


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--items", type=int, default=4)
    ap.add_argument("--vertices", type=int, default=40000)
    ap.add_argument("--max-iter", type=int, default=150)
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 2)
    ap.add_argument("--repeat", type=int, default=1, help="runs per backend (best is shown)")
    args = ap.parse_args(argv)

    env = dict(os.environ, PYTHONPATH=str(REPO))
    one = dict(env, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    w = str(args.workers)
    backends = [("serial", ["--workers", "1"], env),
                (f"{args.items} × sem-pipeline run", None, env),
                ("serial, 1 BLAS thread", ["--workers", "1"], one),
                (f"process pool ×{w}", ["--workers", w], env),
                (f"Dask, running LocalCluster ×{w}", ["--scheduler", "{address}"], env),
                (f"Dask, --scheduler local ×{w} (starts it)",
                 ["--scheduler", "local", "--workers", w], env)]
    print(f"{args.items} items: synthetic face, {args.vertices} vertices, converged mode, "
          f"max_iter {args.max_iter}; {os.cpu_count()} cores; load average before: {load()}")
    with tempfile.TemporaryDirectory(prefix="bench_experiments_") as tmp:
        tmp = Path(tmp)
        config = tmp / "bench.yaml"
        config.write_text(yaml.safe_dump({
            "run": {"name": "bench"}, "input": {"sample": {"vertices": args.vertices}},
            "parameterize": {"mode": "converged", "max_iter": args.max_iter},
            "report": {"figures": False},
            "sweep": {"input.sample.identity": list(range(args.items))}}))
        results = {}
        for k in range(args.repeat):
            for i, (name, extra, e) in enumerate(backends):
                out = tmp / f"out_{k}_{i}"                 # fresh: nothing cached
                if extra is None:
                    result = run_one_by_one(config, out, e)
                elif "{address}" in extra:
                    with dask_cluster(args.workers) as address:
                        result = run(config, out, [address if a == "{address}" else a
                                                   for a in extra], e)
                else:
                    result = run(config, out, extra, e)
                best = results.get(name)
                if best is None or result[0] < best[0]:
                    results[name] = result
    base = results["serial"][0]
    print("\n| backend | wall s | ratio | item s | other work, cores |\n"
          "|---|---:|---:|---:|---:|")
    for name, _, _ in backends:
        wall, items, others = results[name]
        items_s = "" if items != items else f"{items:.1f}"
        print(f"| {name} | {wall:.1f} | {wall / base:.2f} | {items_s} | {others:.2f} |")
    print(f"\nload average after: {load()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
