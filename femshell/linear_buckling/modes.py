"""Azimuthal wavenumber of a buckling mode: Fourier analysis of the mode sampled on circles."""

from __future__ import annotations

import numpy as np

from .eigenproblem import BucklingResult

__all__ = ["azimuthal_wavenumber", "mode_wavenumber"]


def azimuthal_wavenumber(points2d, w_at_points, radius=None, center=(0.0, 0.0), n_max=None,
                         return_spectrum=False):
    """Dominant azimuthal wavenumber of a function sampled on a circle.

    Parameters
    ----------
    points2d : (p, 2) array
        Sample points on a circle about ``center`` (any angular order; angles need not be
        uniform, the Fourier integrals use the trapezoidal rule in the sorted angle).
    w_at_points : (p,) array
        Values there.
    radius : float, optional
        Circle radius for the wavelength (default: mean distance of the points).
    n_max : int, optional
        Largest n considered (default p // 2 - 1).

    Returns
    -------
    (n, wavelength): n the wavenumber with the largest Fourier amplitude (0 for an
    axisymmetric function), wavelength ``2 pi radius / n`` (inf for n = 0). With
    ``return_spectrum=True`` also the amplitudes ``A_n`` (n = 0..n_max) of
    ``w ≈ Σ A_n cos(n θ - φ_n)``.
    """
    x = np.asarray(points2d, float)[:, :2] - np.asarray(center, float)[:2]
    w = np.asarray(w_at_points, float).ravel()
    th = np.arctan2(x[:, 1], x[:, 0])
    order = np.argsort(th)
    th, w = th[order], w[order]
    if radius is None:
        radius = float(np.mean(np.hypot(x[:, 0], x[:, 1])))
    p = len(th)
    n_max = p // 2 - 1 if n_max is None else int(n_max)
    dth = np.diff(np.concatenate([th, [th[0] + 2 * np.pi]]))
    wt = 0.5 * (dth + np.roll(dth, 1))              # periodic trapezoid weights
    ns = np.arange(n_max + 1)
    c = (np.exp(-1j * np.outer(ns, th)) * (w * wt)).sum(1) / (2 * np.pi)
    amp = np.abs(c) * np.where(ns == 0, 1.0, 2.0)
    n = int(np.argmax(amp))
    wavelength = np.inf if n == 0 else 2 * np.pi * radius / n
    if return_spectrum:
        return n, wavelength, amp
    return n, wavelength


def mode_wavenumber(result: BucklingResult, which=0, radii=None, center=(0.0, 0.0), n_samples=512,
                    n_max=60):
    """Azimuthal wavenumber n of mode ``which`` (or of every mode: ``which=None``).

    The mode is sampled at ``n_samples`` equally spaced angles on each circle of
    ``radii`` about ``center`` (default: 0.2, 0.35, ..., 0.95 times the largest circle
    inside the mesh) and the Fourier power spectra of the circles are added, so a mode
    that lives near one radius is still found. Returns (n, wavelength, power) for one
    mode, with the wavelength ``2 pi r / n`` at the circle of largest amplitude, or
    lists of them for ``which=None``.
    """
    mesh = result.basis.mesh
    c = np.asarray(center, float)[:2]
    if radii is None:
        bverts = np.unique(mesh.facets[:, mesh.boundary_facets()])
        rin = np.hypot(*(mesh.p[:, bverts] - c[:, None])).min()
        radii = rin * np.linspace(0.2, 0.95, 6)
    radii = np.atleast_1d(np.asarray(radii, float))
    th = 2 * np.pi * np.arange(n_samples) / n_samples
    n_max = min(n_max, n_samples // 2 - 1)
    idx = slice(None) if which is None else [which]
    k = result.modes[:, idx].shape[1]
    power = np.zeros((n_max + 1, k))
    amp_r = np.zeros((len(radii), k))
    for j, r in enumerate(radii):
        pts = c + r * np.column_stack([np.cos(th), np.sin(th)])
        w = result.basis.probes(pts.T).tocsr() @ result.modes[:, idx]          # (n_samples, k)
        amp = np.abs(np.fft.rfft(w, axis=0)[: n_max + 1]) / n_samples
        amp[1:] *= 2.0
        power += amp ** 2
        amp_r[j] = amp.max(0)
    ns = np.argmax(power, axis=0)
    rbest = radii[np.argmax(amp_r, axis=0)]
    wls = [np.inf if n == 0 else 2 * np.pi * r / n for n, r in zip(ns, rbest)]
    if which is None:
        return [int(n) for n in ns], wls, power
    return int(ns[0]), wls[0], power[:, 0]
