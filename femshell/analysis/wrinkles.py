"""Wrinkle counts: the azimuthal spectrum of a field sampled on circles of a flat (disk) mesh."""

from __future__ import annotations

import math

import numpy as np

from .._checks import finite, finite_vector
from .fields import _count, _field, _mesh


def _sample_on_mesh(xy, tri, v, q):
    """Linear interpolation of a vertex field at points q (k, 2) of a flat triangulation; NaN outside.

    The points are taken in runs of 16 (neighbours on a circle), each tested only against the triangles
    whose bounding box meets the run's: the search over all triangles cost 1.25 s per call at 50 000."""
    a, b, c = xy[tri[:, 0]], xy[tri[:, 1]], xy[tri[:, 2]]
    det = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
    box_lo, box_hi = np.minimum(np.minimum(a, b), c), np.maximum(np.maximum(a, b), c)
    margin = 1e-9 * float(np.ptp(xy, axis=0).max())    # the inside test below admits points 1e-12 outside
    out = np.full(len(q), np.nan)
    tol = -1e-12
    for start in range(0, len(q), 16):
        run = q[start:start + 16]
        lo, hi = run.min(axis=0) - margin, run.max(axis=0) + margin
        near = np.flatnonzero(np.all(box_hi >= lo, axis=1) & np.all(box_lo <= hi, axis=1))
        if not len(near):
            continue
        an, bn, cn, dn = a[near], b[near], c[near], det[near]
        p = run[:, None, :]                                     # (k, 1, 2)
        l1 = ((p[..., 0] - an[:, 0]) * (cn[:, 1] - an[:, 1]) - (cn[:, 0] - an[:, 0]) * (p[..., 1] - an[:, 1])) / dn
        l2 = ((bn[:, 0] - an[:, 0]) * (p[..., 1] - an[:, 1]) - (p[..., 0] - an[:, 0]) * (bn[:, 1] - an[:, 1])) / dn
        l0 = 1.0 - l1 - l2
        inside = (l0 >= tol) & (l1 >= tol) & (l2 >= tol)      # (k, candidates)
        has = inside.any(axis=1)
        j = np.argmax(inside, axis=1)
        r = np.arange(len(j))
        t = tri[near[j]]
        val = l0[r, j] * v[t[:, 0]] + l1[r, j] * v[t[:, 1]] + l2[r, j] * v[t[:, 2]]
        out[start:start + 16] = np.where(has, val, np.nan)
    return out


def _circle_samples(points, values, radius, center, n_samples, triangles):
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] not in (2, 3):
        raise ValueError(f"points must have shape (n, 2) or (n, 3), got {pts.shape}")
    v = _field(values, len(pts), "values")
    if pts.shape[1] == 3:   # a circle in the xy plane: a curved mesh would be silently projected onto it
        extent = max(np.ptp(pts[:, 0]), np.ptp(pts[:, 1]))
        if np.ptp(pts[:, 2]) > 1e-9 * extent:
            raise ValueError(f"points must be a flat mesh in the xy plane (the reference positions), got z from "
                             f"{pts[:, 2].min():.6g} to {pts[:, 2].max():.6g}")
    radius = finite("radius", radius, 0.0, lo_open=True)
    ns = _count("n_samples", n_samples, 8, 1_000_000)
    phi = 2 * math.pi * np.arange(ns) / ns
    cx, cy = finite_vector("center", center, 2)
    q = np.column_stack([cx + radius * np.cos(phi), cy + radius * np.sin(phi)])
    if triangles is not None:
        tri = _mesh(pts, triangles)[1]
        if not len(tri):
            raise ValueError("triangles is empty: no mesh to sample the circle on")
        w = _sample_on_mesh(pts[:, :2], tri, v, q)
    else:
        from scipy.interpolate import LinearNDInterpolator   # deferred: scipy.interpolate is slow to import, needed only here
        from scipy.spatial import QhullError

        if not np.all(np.isfinite(pts)):
            raise ValueError("points hold NaN or infinity")
        try:
            w = LinearNDInterpolator(pts[:, :2], v)(q)
        except (QhullError, ValueError) as exc:   # fewer than 3 points, or all on a line
            raise ValueError(f"cannot triangulate the points in the xy plane ({str(exc).splitlines()[0]}); "
                             "pass the mesh's triangles") from None
    if not np.all(np.isfinite(w)):
        raise ValueError(f"the circle of radius {radius} about {center} leaves the mesh")
    return w


def _spectrum(w):
    ns = len(w)
    amp = np.abs(np.fft.rfft(w)) / ns
    amp[1:] *= 2.0
    if ns % 2 == 0:
        amp[-1] /= 2.0
    return amp


def azimuthal_spectrum(points, values, radius: float, *, center=(0.0, 0.0), n_samples: int = 512,
                       triangles=None):
    """Fourier amplitudes |ŵ_k| (k = 0 .. n_samples/2) of a field sampled on a circle.

    ``points`` are the (reference) positions (n, 2) or (n, 3) of a flat mesh in the xy
    plane, ``values`` (n,) a vertex field (e.g. the deflection w), sampled by linear
    interpolation at ``n_samples`` angles on the circle of ``radius`` about ``center``:
    on the mesh's own ``triangles`` when given, else on a Delaunay triangulation of the
    points (slower). Amplitudes are in the unit of ``values``:
    w(φ) = ŵ_0 + Σ_k ŵ_k cos(k φ − φ_k). Raises ValueError when the circle leaves the mesh.
    """
    return _spectrum(_circle_samples(points, values, radius, center, n_samples, triangles))


def azimuthal_power(points, values, radii, *, triangles=None, skip_outside: bool = False):
    """|ŵ_k|² (k = 0 .. 256) summed over the circles of the given ``radii`` about the origin.

    One circle can pass where a mode's part of some wavenumber vanishes; the sum over several
    does not. See :func:`azimuthal_spectrum` (512 samples per circle). A circle that leaves
    the mesh raises ValueError, or with ``skip_outside`` is left out; None if none is left.
    """
    power = None
    for r in radii:
        try:
            amp = azimuthal_spectrum(points, values, r, triangles=triangles)
        except ValueError:
            if not skip_outside:
                raise
            continue
        power = amp ** 2 if power is None else power + amp ** 2
    return power


def count_wrinkles(points, values, radius: float, *, center=(0.0, 0.0), n_samples: int = 512,
                   triangles=None, min_mode: int = 1, rel_tol: float = 1e-3, method: str = "fourier") -> int:
    """Number of azimuthal wrinkles of a field (the deflection w) on a circle of ``radius``.

    ``method="fourier"``: the dominant azimuthal mode k ≥ ``min_mode`` of w(φ) (w ∝ cos kφ
    has k wrinkles). ``method="zeros"``: half the number of sign changes of w(φ) − mean.
    Returns 0 when the non-axisymmetric part is below ``rel_tol`` of the total amplitude
    on the circle (an axisymmetric or flat state). ``min_mode=2`` ignores a tilt (k = 1).
    See :func:`azimuthal_spectrum` for the sampling (pass ``triangles`` for speed).

    >>> import numpy as np
    >>> from femshell.mesh.generators import disk
    >>> from femshell.analysis import count_wrinkles
    >>> d = disk(radius=5.0, edge_length=0.25)
    >>> x, y = d.points[:, 0], d.points[:, 1]
    >>> count_wrinkles(d.points, np.hypot(x, y) ** 2 * np.cos(5 * np.arctan2(y, x)), 3.0, triangles=d.triangles)
    5
    """
    if method not in ("fourier", "zeros"):
        raise ValueError(f"method must be 'fourier' or 'zeros', got {method!r}")
    w = _circle_samples(points, values, radius, center, n_samples, triangles)
    min_mode = _count("min_mode", min_mode, 1, len(w) // 2)
    rel_tol = finite("rel_tol", rel_tol, 0.0, 1.0)
    amp = _spectrum(w)
    scale = amp[0] + amp[1:].sum()
    modes = amp[int(min_mode):]
    if scale == 0 or modes.max() <= rel_tol * scale:
        return 0
    if method == "fourier":
        return int(min_mode + int(np.argmax(modes)))
    d = w - w.mean()
    s = np.sign(d)
    s[s == 0] = 1
    return int(np.count_nonzero(s != np.roll(s, 1)) // 2)
