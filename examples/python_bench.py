"""Throughput of npf from Python (BENCHMARKS.md, "Python"): batched eval,
sampling and pdf in pairs per second, and a fit from Python against the same
fit by the npf program.

    python examples/python_bench.py [--n 2000000] [--repeats 5] [--npf target/release/npf]

Every figure is the median of --repeats runs; the machine is shared, so
compare figures from one run only.
"""

import argparse
import math
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import npf

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "python" / "tests"))
from _helpers import known_factor_model, random_directions  # noqa: E402


def median_time(f, repeats):
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        f()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=2_000_000, help="pairs per batch")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--fit-sweeps", type=int, default=20)
    ap.add_argument("--npf", default=os.environ.get("NPF_BIN") or shutil.which("npf") or "target/release/npf")
    args = ap.parse_args()

    model = known_factor_model((0.05, 0.2, 0.5))
    rng = np.random.default_rng(0)
    n = args.n
    wi, wo = random_directions(rng, n), random_directions(rng, n)
    u = rng.random((n, 3))
    model.sample(wo[:10], u[:10])  # build the sampler's tables first

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"npf {npf.__version__}, {os.cpu_count()} cores (load {load:.1f}), batches of {n:,} (median of {args.repeats})")
    # Wall time (what a caller waits) and the process's CPU time (all
    # threads): on a shared, loaded machine pairs per CPU-second x cores is
    # the throughput of the same work on free cores.
    cores = os.cpu_count() or 1
    calls = {
        "eval": lambda: model.eval(wi, wo),
        "sample": lambda: model.sample(wo, u),
        "pdf": lambda: model.pdf(wo, wi),
    }
    kernel = {k: [] for k in calls}
    for _ in range(args.repeats):
        for k, t in zip(calls, model._kernel_seconds(wi, wo, u)):
            kernel[k].append(t)
    print(f"  {'call':8s} {'wall M/s':>9s} {'CPU-s M/s x cores':>18s} {'kernel only M/s':>16s}")
    for name, f in calls.items():
        wall, cpu = [], []
        for _ in range(args.repeats):
            t, c = time.perf_counter(), time.process_time()
            f()
            wall.append(time.perf_counter() - t)
            cpu.append(time.process_time() - c)
        w, c, k = statistics.median(wall), statistics.median(cpu), statistics.median(kernel[name])
        print(f"  {name:8s} {n / w / 1e6:9.2f} {n / (c / cores) / 1e6:18.2f} {n / k / 1e6:16.2f}")

    # The same fit from Python and from the CLI (same table, same options).
    with tempfile.TemporaryDirectory() as d:
        table = Path(d) / "known.binary"
        npf.write_merl(table, known_factor_model((0.1, 0.4)).reconstruct())
        opts = ["--lobes", "2", "--max-sweeps", str(args.fit_sweeps), "--tol", "0"]
        py, cli, py_cpu, cli_cpu = [], [], [], []
        for k in range(max(1, args.repeats // 2)):
            t, c = time.perf_counter(), time.process_time()
            m = npf.fit(table, lobes=2, max_sweeps=args.fit_sweeps, tol=0.0)
            py.append(time.perf_counter() - t)
            py_cpu.append(time.process_time() - c)
            if Path(args.npf).exists():
                t, c = time.perf_counter(), os.times()
                subprocess.run([args.npf, "fit", table, "-o", Path(d) / f"cli{k}.npfb", *opts, "--quiet"], check=True)
                cli.append(time.perf_counter() - t)
                e = os.times()
                cli_cpu.append(e.children_user - c.children_user + e.children_system - c.children_system)
        med = statistics.median
        print(f"  fit, 2 lobes, {m.fit_info['sweeps']} sweeps: Python {med(py):.2f} s wall, {med(py_cpu):.2f} s CPU", end="")
        if cli:
            print(
                f"; npf fit {med(cli):.2f} s wall, {med(cli_cpu):.2f} s CPU"
                f" (Python / CLI: wall {med(py) / med(cli):.2f}, CPU {med(py_cpu) / med(cli_cpu):.2f})"
            )
        else:
            print(f" (no npf program at {args.npf}: CLI not timed)")


if __name__ == "__main__":
    main()
