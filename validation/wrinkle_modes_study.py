"""Which rim wavenumbers are stable states of the paper's disk? Starts seeded with one azimuthal wave.

The paper counts 8 wrinkles on its disk at h = 0.25, R2 = 3, ε = 0.5; the broadband starts of
`wrinkle_seeds_study.py` end at n = 2 … 6 there (docs/studies/disk-crosscheck.md). Is a state with k
wrinkles a local minimum of the shell that those starts miss, or does the disk leave such a wave?
Each sample starts from one wave cos(kφ + φ₀) of amplitude A·h on the rim band, on the small dome
(:func:`femshell.validation.wrinkle_scaling.seed_shape`, phase φ₀ from ``--seed``), and raises ε to its
value in steps of 0.05 with saddle-escaping Newton, as the `wrinkle-scaling` case does. Recorded per
sample: the end state's dominant rim wavenumber n and amplitude (wrinkled from 0.05 of the
axisymmetric part), energy and negative eigenvalues. k survives when the end state is stable with
n = k.

Each finished sample is written to the JSON at once; running the same command again skips the
samples already there (stop it any time). The committed result
(validation/results/studies/wrinkle-modes.json, table in docs/studies/disk-crosscheck.md) is

    .venv/bin/python validation/wrinkle_modes_study.py --k 2 3 4 5 6 7 8 9 10 11 12 14 16 --amplitude 1.5
    .venv/bin/python validation/wrinkle_modes_study.py --k 8 --amplitude 0.3

with the defaults --h 0.25 --eps 0.5 --resolution 12 --seed 1.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from femshell.io import atomic_write_json
from femshell.validation import wrinkle_scaling as ws
from femshell.validation.disk import warm_up


def table(samples):
    """Markdown rows: seeded k, amplitude, end n, rim amplitude, energy above the lowest stable sample."""
    stable = [s["energy"] for s in samples if s["n_negative"] == 0]
    lowest = min(stable) if stable else None
    out = ["| seeded k | amplitude / h | end n | rim amplitude | energy | above the lowest stable | "
           "negative eigenvalues | Newton failures | wall [s] |", "|---|---|---|---|---|---|---|---|---|"]
    for s in sorted(samples, key=lambda s: (s["modes"], s["waves"])):
        above = "–" if lowest is None or s["n_negative"] != 0 else f"{100 * (s['energy'] / lowest - 1):+.2f} %"
        out.append(f"| {s['modes'][0]} | {s['waves']:g} | {s['n']} | {s['rel']:.3f} | {s['energy']:.8g} | {above} | "
                   f"{s['n_negative']} | {s['newton_failures']} | {s['wall_s']:.0f} |")
    return "\n".join(out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--k", type=int, nargs="+", required=True, help="azimuthal wavenumbers to seed (>= 2)")
    ap.add_argument("--amplitude", type=float, nargs="+", default=[ws.SEED_WAVES],
                    help=f"wave amplitudes in units of h (default {ws.SEED_WAVES:g}, the broadband start's)")
    ap.add_argument("--h", type=float, default=0.25)
    ap.add_argument("--eps", type=float, default=ws.EPS_FIXED)
    ap.add_argument("--resolution", type=int, default=12)
    ap.add_argument("--seed", type=int, default=ws.SEED, help="random-number seed of the wave's phase")
    ap.add_argument("--json", type=Path, default=Path("validation/results/studies/wrinkle-modes.json"))
    ap.add_argument("--checkpoints", type=Path, default=Path("validation-out/wrinkle-modes"),
                    help="where a sample in progress is saved after every eps step")
    a = ap.parse_args(argv)
    if not 0.0 < a.eps <= 1.0 or a.h <= 0.0 or a.resolution < 2:
        ap.error("need 0 < eps <= 1, h > 0 and resolution >= 2")
    if min(a.k) < 2 or min(a.amplitude) <= 0.0:
        ap.error(f"--k must be >= 2 (k = 0, 1 are the dome and a tilt) and --amplitude > 0, got {a.k}, {a.amplitude}")
    samples = json.loads(a.json.read_text())["samples"] if a.json.exists() else []
    other = {(s["h"], s["eps"], s["resolution"], s["seed"]) for s in samples} - {(a.h, a.eps, a.resolution, a.seed)}
    if other:       # the energies are compared across the file's samples
        ap.error(f"{a.json} holds samples at (h, eps, resolution, seed) = {sorted(other)}; use another --json")
    done = {(s["modes"][0], s["waves"]) for s in samples}
    warm_up()
    for k in a.k:
        for amp in a.amplitude:
            if (k, amp) in done:
                continue
            a.checkpoints.mkdir(parents=True, exist_ok=True)
            ck = a.checkpoints / f"h{a.h:g}-eps{a.eps:g}-res{a.resolution}-seed{a.seed}-k{k}-a{amp:g}.npz"
            s = ws.seeded_sample(a.h, a.eps, a.resolution, a.seed, waves=amp, modes=(k,), checkpoint=ck)
            s.update(modes=[k], waves=amp)
            print(f"k = {k}, amplitude {amp:g} h: end n = {s['n']}, rim amplitude {s['rel']:.3g}, energy "
                  f"{s['energy']:.8g}, {s['n_negative']} negative eigenvalues ({s['wall_s']:.0f} s)"
                  f"{'; ' + s['error'] if s['error'] else ''}", flush=True)
            samples.append(s)
            a.json.parent.mkdir(parents=True, exist_ok=True)
            atomic_write_json(a.json, {"study": "wrinkle-modes", "R2": ws.R2, "rel_tol": ws.REL_TOL,
                                       "samples": samples})
            for p in (ck, ck.with_name(ck.name + ".prev")):      # recorded: its checkpoint is not needed
                p.unlink(missing_ok=True)
    print(table(samples))


if __name__ == "__main__":
    main()
