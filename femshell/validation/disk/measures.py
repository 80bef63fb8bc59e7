r"""What the disk study measures on a state: the wrinkle count, the rim's lobes, and which state counts.

The count (issue 4): the deflection w (best-fit plane removed) on the material circle r = ``COUNT_RADIUS`` · R2
just outside the grown region, its dominant azimuthal Fourier mode k ≥ 2 (:func:`femshell.analysis.count_wrinkles`),
0 when the non-axisymmetric part is below ``REL_TOL`` of the amplitude or w is flat (``FLAT_TOL`` · h). The rim
mode: the dominant k ≥ 2 on circles inside the rim (``INNER_RIM_RADII``) and its amplitude relative to the
axisymmetric part, √(P_k / P_0) of the summed powers. The selection rule: of several end states of one case the
lowest-energy resolved stable equilibrium counts (:func:`select_lowest`, :func:`with_carried`). The paper's
counts (Zakharov & Dasbiswas, section 4; theory §1.6) are :func:`paper_count`.

The functions take a disk (:class:`~femshell.validation.disk.model.Disk`: ``points``, ``triangles``, ``h``,
``R2`` and ``mode_deflection``) and a field on its vertices.
"""

from __future__ import annotations

import math

import numpy as np

from ...analysis import azimuthal_power as _circle_power
from ...analysis import azimuthal_spectrum, count_wrinkles

#: the paper's R2 where the count at h = 2 becomes 2, 3, 4, the R2 its h = 2 counts span (issue 4's grid),
#: and its count at h = 0.25, R2 = 3
PAPER_CHANGES = {2: 1.95, 3: 2.9, 4: 3.9}
PAPER_R2_RANGE = (1.0, 4.5)
PAPER_THIN = (0.25, 3.0, 8)
#: the counting circle (material radius / R2) and the non-axisymmetric threshold
COUNT_RADIUS = 1.15
#: a deflection of at most this · h is flat (count 0): the Fourier modes of round-off (|w| ~ 1e-23) would
#: otherwise read as wrinkles
FLAT_TOL = 1e-9
REL_TOL = 0.05
#: circles (radius / R2) inside the rim of the grown region where its lobes are measured (reported beside the
#: count, which is taken just outside R2 as issue 4 asks: a lobed rim whose lobes fade outside counts 0 there)
INNER_RIM_RADII = (0.7, 0.8, 0.9, 1.0)
#: a carried state is counted only when its energy is below the case's own by more than this (relative): one
#: state reached both ways differs by round-off, distinct ones by 1e-5 to 1e-2
SAME_STATE_RTOL = 1e-9


def paper_count(h, R2):
    """The paper's wrinkle count at ε = 0.5, or None where it gives none (theory §1.6; at h = 2 only for
    R2 in ``PAPER_R2_RANGE``: its count of 4 from R2 = 3.9 is not extended to larger disks)."""
    if h == PAPER_THIN[0] and R2 == PAPER_THIN[1]:
        return PAPER_THIN[2]
    if h != 2.0 or not PAPER_R2_RANGE[0] <= R2 <= PAPER_R2_RANGE[1]:
        return None
    n = 0
    for k, r in PAPER_CHANGES.items():
        if R2 >= r:
            n = k
    return n


def wrinkle_count(disk, w):
    """Wrinkles of w on the material circle r = COUNT_RADIUS · R2 (0: axisymmetric, or flat: |w| at most
    ``FLAT_TOL`` · h everywhere, where the ratio of its Fourier modes is round-off's)."""
    if np.abs(w).max() <= FLAT_TOL * disk.h:
        return 0
    return count_wrinkles(disk.points, w, COUNT_RADIUS * disk.R2, triangles=disk.triangles, min_mode=2,
                          rel_tol=REL_TOL)


def counting_spectrum(disk, w, k_max=16):
    """|ŵ_k|, k = 0..k_max, on the counting circle."""
    return azimuthal_spectrum(disk.points, w, COUNT_RADIUS * disk.R2, triangles=disk.triangles)[: k_max + 1]


def azimuthal_power(disk, z, radii, k_max=24):
    """|ẑ_k|², k = 0..k_max, summed over the material circles r = radii · R2."""
    return _circle_power(disk.points, z, [f * disk.R2 for f in radii], triangles=disk.triangles)[: k_max + 1]


def rim_mode(disk, w, radii=INNER_RIM_RADII, k_max=24):
    """Dominant azimuthal wavenumber k ≥ 2 of w on the circles r = radii · R2 and its amplitude relative
    to the axisymmetric part (root of the summed powers): (k, relative amplitude)."""
    power = azimuthal_power(disk, w, radii, k_max)
    k = 2 + int(np.argmax(power[2:]))
    return k, float(math.sqrt(power[k] / max(power[0], 1e-300)))


def mode_wavenumber(disk, modes):
    """Dominant azimuthal wavenumber of the out-of-plane part of critical mode(s) (best-fit plane
    removed), summed power on circles r = (0.5, 0.85, 1.15, 1.5) R2."""
    power = sum(azimuthal_power(disk, disk.mode_deflection(v), (0.5, 0.85, 1.15, 1.5))
                for v in np.atleast_2d(np.asarray(modes).T))
    return int(np.argmax(power))


def select_lowest(candidates):
    """Index of the end state among relaxation ``candidates`` (dicts with energy and result): the lowest-energy
    one that is a result (a resolved stable equilibrium), else the first. Past a snap lie several stable states
    of nearly the same energy and round-off decides which one a single relaxation reaches; the lowest of
    several is the shell's most likely state."""
    ok = [i for i, c in enumerate(candidates) if c["result"]]
    return min(ok, key=lambda i: candidates[i]["energy"]) if ok else 0


def with_carried(u, rec, carried):
    """A case's end state after the exchange: (u, record) of the lowest-energy resolved stable equilibrium among
    its own state (u, ``rec``, :func:`~.cases.case_record`) and the ``carried`` ones ((u, candidate) of
    :func:`~.exchange.carried_to_neighbour`); its own when none is lower by more than ``SAME_STATE_RTOL``. The record
    gains ``carried`` (the candidates) and ``counted_from`` (the R2 the counted state came from, None for its
    own), and its final-state numbers become those of the counted state."""
    own = dict(energy=rec["energy"], result=rec["result"])
    k = select_lowest([own] + [c for _, c in carried])
    rec = dict(rec, carried=[c for _, c in carried], counted_from=None)
    if k == 0:
        return u, rec
    u_c, c = carried[k - 1]
    if own["result"] and own["energy"] - c["energy"] <= SAME_STATE_RTOL * abs(own["energy"]):
        return u, rec
    u = u_c
    rec.update(count=c["count"], rim=c["rim"], energy=c["energy"], result=c["result"], n_negative_final=c["n_negative"],
               residual=c["residual"], over_folded=c["over_folded"], largest_turn=c["largest_turn"],
               counted_from=c["from_R2"])
    return u, rec

