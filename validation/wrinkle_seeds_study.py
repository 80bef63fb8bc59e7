"""How the rim wavenumber n of the paper's disk is distributed over random seeds, and λ against h from it.

The `wrinkle-scaling` case measures one state per (h, ε): the lower-energy end of two starts. Its n
moves by ±1-2 with the start, the mesh and round-off (docs/studies/disk-crosscheck.md), so one sample per h
cannot give an exponent. This study samples: per (h, ε), the broadband start of
:func:`femshell.validation.wrinkle_scaling.seeded_state` with the wave phases of seeds 1 … K (everything
else as in the case). Per sample: n, rim amplitude, energy, negative eigenvalues. Per h: the values
of n of the wrinkled stable samples, their mean and standard error, and the n of the lowest-energy
sample. The exponent of λ = 2π R2/n against h is fitted over all wrinkled stable samples
(:func:`~femshell.validation.wrinkle_scaling.fit_exponent`: its √(χ²/dof) scaling turns the
seed-to-seed scatter into the uncertainty).

Each finished sample is written to the JSON at once; running the same command again skips the
samples already there (stop it any time).

    .venv/bin/python validation/wrinkle_seeds_study.py --h 0.25 0.5 --seeds 1 2 3 4 5 6 \\
        [--eps 0.5] [--resolution 12] [--json validation/results/studies/wrinkle-seeds.json]
"""

from __future__ import annotations

import argparse
import fcntl
import json
import math
from pathlib import Path

import numpy as np

from femshell.io import atomic_write_json
from femshell.validation import wrinkle_scaling as ws
from femshell.validation.disk import warm_up


def read_samples(path):
    return json.loads(path.read_text())["samples"] if path.exists() else []


def summarise(samples):
    """Per h: n of the wrinkled stable samples, mean ± standard error, n of the lowest energy; the fit."""
    ok = [s for s in samples if s["rel"] >= ws.REL_TOL and s["n_negative"] == 0]
    per_h = {}
    for h in sorted({s["h"] for s in samples}):
        all_h = [s for s in samples if s["h"] == h]
        ns = [s["n"] for s in ok if s["h"] == h]
        lowest = min(all_h, key=lambda s: s["energy"])
        per_h[f"{h:g}"] = {"samples": len(all_h), "wrinkled_stable": len(ns), "n": ns,
                           "n_mean": float(np.mean(ns)) if ns else None,
                           "n_sem": float(np.std(ns, ddof=1) / math.sqrt(len(ns))) if len(ns) > 1 else None,
                           "n_lowest_energy": lowest["n"], "lowest_is_wrinkled": lowest in ok}
    p, sp = ws.fit_exponent([s["h"] for s in ok], [s["n"] for s in ok])
    fit = None if math.isnan(p) else {"exponent": p, "sigma": sp, "cerda_mahadevan": ws.REFERENCE["h"]}
    return per_h, fit


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--h", type=float, nargs="+", required=True)
    ap.add_argument("--seeds", type=int, nargs="+", required=True)
    ap.add_argument("--eps", type=float, default=ws.EPS_FIXED)
    ap.add_argument("--resolution", type=int, default=12)
    ap.add_argument("--json", type=Path, default=Path("validation/results/studies/wrinkle-seeds.json"),
                    help="records, new states added to it (default: the committed "
                         "validation/results/studies/wrinkle-seeds.json)")
    ap.add_argument("--checkpoints", type=Path, default=Path("validation-out/wrinkle-seeds"),
                    help="where a sample in progress is saved after every eps step (up to 15 min each)")
    a = ap.parse_args(argv)
    if not 0.0 < a.eps <= 1.0 or min(a.h) <= 0.0 or a.resolution < 2:
        ap.error("need 0 < eps <= 1, h > 0 and resolution >= 2")
    if min(a.seeds) < 0:
        ap.error(f"--seeds must be integers >= 0 (random-number seeds), got {a.seeds}")
    samples = read_samples(a.json)
    other = {(s["eps"], s["resolution"]) for s in samples} - {(a.eps, a.resolution)}
    if other:       # the summary groups by h only
        ap.error(f"{a.json} holds samples at (eps, resolution) = {sorted(other)}; use another --json for "
                 f"eps = {a.eps:g}, resolution {a.resolution}")
    done = {(s["h"], s["eps"], s["resolution"], s["seed"]) for s in samples}
    warm_up()
    for h in a.h:
        for seed in a.seeds:
            if (h, a.eps, a.resolution, seed) in done:
                continue
            a.checkpoints.mkdir(parents=True, exist_ok=True)
            ck = a.checkpoints / f"h{h:g}-eps{a.eps:g}-res{a.resolution}-seed{seed}.npz"
            s = ws.seeded_sample(h, a.eps, a.resolution, seed, checkpoint=ck)
            print(f"h={h:g} eps={a.eps:g} resolution {a.resolution} seed {seed}: n = {s['n']}, rim amplitude "
                  f"{s['rel']:.3g}, energy {s['energy']:.8g}, {s['n_negative']} negative eigenvalues "
                  f"({s['wall_s']:.0f} s){'; ' + s['error'] if s['error'] else ''}", flush=True)
            a.json.parent.mkdir(parents=True, exist_ok=True)
            with open(a.json.with_name(a.json.name + ".lock"), "w") as lock:
                fcntl.flock(lock, fcntl.LOCK_EX)    # two processes (one per h) share the file: merge, never overwrite
                samples = read_samples(a.json) + [s]
                per_h, fit = summarise(samples)
                atomic_write_json(a.json, {"study": "wrinkle-seeds", "R2": ws.R2, "rel_tol": ws.REL_TOL,
                                           "samples": samples, "per_h": per_h, "fit": fit})
            for p in (ck, ck.with_name(ck.name + ".prev")):      # recorded: its checkpoint is not needed
                p.unlink(missing_ok=True)
    per_h, fit = summarise(read_samples(a.json))     # with what another process added meanwhile
    for h, v in per_h.items():
        print(f"h={h}: n = {v['n']} (mean {v['n_mean']}, s.e. {v['n_sem']}), lowest energy n = {v['n_lowest_energy']}")
    print("fit:", fit)


if __name__ == "__main__":
    main()
