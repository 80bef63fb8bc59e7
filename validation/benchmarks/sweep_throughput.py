"""Throughput of ``femshell sweep`` on 1 and 2 local workers: the same 4 points, one after the other in one run.

Each sweep starts its own LocalCluster (worker start-up and JAX's cached kernels included, as a user
sees them). Printed side by side: wall time, points per minute, the CPU time of the workers
(the children's rusage, collected when the cluster closes) and the ratio; with ``uptime``'s load,
since other jobs on the cores change the wall times.

    python validation/benchmarks/sweep_throughput.py [--vertices 400] [--t-final 0.3] [--out DIR]
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import sys
import tempfile
import time
from pathlib import Path

import femshell

SPEC = """description = "throughput: 4 points"
scene = "default"
mode = "zip"
[set]
"mesh.n_vertices" = {vertices}
"solver.t_final" = {t_final}
"output.pictures" = false
[vary]
"growth.c_star" = [0.1, 0.2, 0.3, 0.35]
"""


def children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def one(spec, out, workers):
    from femshell.sweep import run_sweep

    cpu0, t0 = children_cpu(), time.perf_counter()
    with open(os.devnull, "w") as quiet:
        code = run_sweep(spec, out, workers=workers, plot=False, stream=quiet)
    return code, time.perf_counter() - t0, children_cpu() - cpu0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vertices", type=int, default=400)
    ap.add_argument("--t-final", type=float, default=0.3)
    ap.add_argument("--out", help="keep the sweeps here (default: a temporary directory, deleted)")
    args = ap.parse_args(argv)
    femshell.configure()
    from femshell.sweep import load_spec

    root = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="femshell-sweep-bench-"))
    root.mkdir(parents=True, exist_ok=True)
    spec_path = root / "spec.toml"
    spec_path.write_text(SPEC.format(vertices=args.vertices, t_final=args.t_final))
    spec = load_spec(spec_path)
    print(f"load before: {os.getloadavg()[0]:.2f} (1 min) on {os.cpu_count()} CPUs; 4 points, "
          f"{args.vertices} vertices, t_final {args.t_final}")
    res = {}
    for n in (1, 2):
        out = root / f"workers-{n}"
        shutil.rmtree(out, ignore_errors=True)
        res[n] = one(spec, out, n)
        print(f"  {n} worker(s): exit {res[n][0]}, wall {res[n][1]:7.1f} s, {4 * 60 / res[n][1]:5.2f} points/min, "
              f"workers' CPU {res[n][2]:7.1f} s; load now {os.getloadavg()[0]:.2f}", flush=True)
    print(f"throughput 2 workers / 1 worker: {res[1][1] / res[2][1]:.2f} (wall ratio), "
          f"CPU 2/1: {res[2][2] / max(res[1][2], 1e-9):.2f}")
    if not args.out:
        shutil.rmtree(root, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
