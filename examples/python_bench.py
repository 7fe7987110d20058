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

    print(f"npf {npf.__version__}, {os.cpu_count()} cores, batches of {n:,} (median of {args.repeats})")
    rows = []
    for name, f in [
        ("eval(wi, wo)", lambda: model.eval(wi, wo)),
        ("sample(wo, u)", lambda: model.sample(wo, u)),
        ("pdf(wo, wi)", lambda: model.pdf(wo, wi)),
    ]:
        t = median_time(f, args.repeats)
        rows.append((name, n / t / 1e6))
        print(f"  {name:15s} {n / t / 1e6:7.2f} M/s  ({t * 1e3:.0f} ms per batch)")

    # The same fit from Python and from the CLI (same table, same options).
    with tempfile.TemporaryDirectory() as d:
        table = Path(d) / "known.binary"
        npf.write_merl(table, known_factor_model((0.1, 0.4)).reconstruct())
        opts = ["--lobes", "2", "--max-sweeps", str(args.fit_sweeps), "--tol", "0"]
        py, cli = [], []
        for k in range(max(1, args.repeats // 2)):
            t = time.perf_counter()
            m = npf.fit(table, lobes=2, max_sweeps=args.fit_sweeps, tol=0.0)
            py.append(time.perf_counter() - t)
            if Path(args.npf).exists():
                t = time.perf_counter()
                subprocess.run([args.npf, "fit", table, "-o", Path(d) / f"cli{k}.npfb", *opts, "--quiet"], check=True)
                cli.append(time.perf_counter() - t)
        print(f"  fit, 2 lobes, {m.fit_info['sweeps']} sweeps: Python {statistics.median(py):.2f} s", end="")
        if cli:
            print(f", npf fit {statistics.median(cli):.2f} s (ratio {statistics.median(py) / statistics.median(cli):.2f})")
        else:
            print(f" (no npf program at {args.npf}: CLI not timed)")


if __name__ == "__main__":
    main()
