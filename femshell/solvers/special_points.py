"""Special points between two accepted points of a branch: detection, location, multiplicity.

* *fold* ("LP"): dλ/ds changes sign; located by Illinois (safeguarded regula falsi) on t_λ
  as a function of the arclength σ from the step's start;
* *branch point* ("BP"): the number of negative eigenvalues of K changes without a fold;
  located by Illinois on the eigenvalue that crosses zero, one crossing after the other;
* *possible symmetric bifurcation* ("BP?"): an eigenvalue dips towards zero between three
  accepted points without changing sign; flagged at the vertex of the fitted parabola.

For a **non-gradient** problem (residual and unsymmetric Jacobian J, no inertia) the branch points
are the sign changes of τ = sign(det J)·sign(t_λ), the sign of the determinant of the augmented
Jacobian [[J, g_λ], [tᵀ, 0]] (Cramer: t_λ = det J / det of it), which stays non-zero at a fold;
each is located by Illinois on the smooth test function ψ = −1/(cᵀ J⁻¹ b) = det J / det [[J, b],
[cᵀ, 0]] with b, c the right and left null vectors of J at an end of the step (ψ vanishes where
J is singular, and changes sign with det J). Its critical mode is the null vector of J there;
its multiplicity is reported as 1 (a sign change detects an odd number of crossings).

The multiplicity counts the eigenvalues whose straight-line extrapolation in σ vanishes within
``cluster_tol`` × max(|λ*|, λ_scale) of the located point (cos nθ, sin nθ of a disk: one double
point). :class:`_Context` also keeps the branch's table rows.
"""

from __future__ import annotations

import math
import time

import numpy as np

from .branch import SpecialPoint
from .corrector import _StepFailure

#: an eigenvalue below this fraction of max|diag K| at both ends of a step is a null mode, not a crossing
NULL_EIG_TOL = 1e-10
#: crossings located per step; more in one step are reported, not located
MAX_CROSSINGS_PER_STEP = 8


class _Context:
    """Rows, detection and location of special points for one continuation run."""

    def __init__(self, eng, branch, record, keep_states, n_eigs, locate_tol, cluster_tol, dip_tol, log, t0):
        self.eng, self.branch, self.record = eng, branch, record
        self.keep_states, self.n_eigs = keep_states, n_eigs
        self.locate_tol, self.cluster_tol, self.dip_tol = locate_tol, cluster_tol, dip_tol
        self.log, self.t0 = log, t0
        self._step_end = None       # the end of the step being searched (an unlocated point is reported there)

    @property
    def max_crossings(self):
        """The most crossings one step can locate: MAX_CROSSINGS_PER_STEP points, each of multiplicity up to
        the window of eigenvalues searched."""
        return MAX_CROSSINGS_PER_STEP * max(self.n_eigs, 4)

    # ---- rows
    def add_row(self, P, s, step, ds, special=""):
        row = {"step": step, "s": s, "parameter": P.lam, "energy": P.energy, "n_negative": P.n_negative,
               "stable": None if P.n_negative is None else P.n_negative == 0}
        if self.eng.general:
            stability = self.eng.stability(P) or {"stable": None}
            row["stable"] = None if stability["stable"] is None else bool(stability["stable"])
            row["det_sign"] = P.det_sign
            row.update({k: v for k, v in stability.items() if k != "stable"})
        for i in range(self.n_eigs):
            ev = P.eigenvalues
            row[f"eig_{i}"] = float(ev[i]) if ev is not None and i < len(ev) else math.nan
        row.update({"dlam_ds": P.t_lam, "ds": ds, "iterations": P.iterations, "special": special,
                    "branch": self.branch.label, "wall_s": time.perf_counter() - self.t0})
        extra = self.record(P.u) or {}
        if not isinstance(extra, dict):
            raise TypeError(f"record(u) must return a dict of columns, got {type(extra).__name__}")
        clash = sorted(set(extra) & set(row))
        if clash:
            raise ValueError(f"record(u) returned column(s) {', '.join(clash)} that the branch table already has")
        row.update({k: (float(v) if isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)
                        else v) for k, v in extra.items()})
        self.branch.rows.append(row)
        self.branch.states.append((P.u, P.lam) if self.keep_states else None)

    # ---- trial points along the step from A
    def point_at(self, A, sigma, n_eigs, cache):
        key = float(sigma)
        P = cache.get(key)
        if P is not None:
            return self._with_eigs(P, n_eigs) if n_eigs > 0 else P
        eng = self.eng
        P = eng.correct(A.u + sigma * A.t_u, A.lam + sigma * A.t_lam, t=(A.t_u, A.t_lam),
                        max_dist=max(abs(sigma), 1e-300) * 2)
        P = eng.finish(P, (A.t_u, A.t_lam), n_eigs=n_eigs)
        cache[key] = P
        return P

    def _with_eigs(self, P, k, vectors=False):
        """Make sure P has the k eigenvalues nearest zero (and vectors); K is kept on the point."""
        have = P.eigenvalues is not None and len(P.eigenvalues) >= min(k, len(P.u))
        if k <= 0 or (have and (P.eigenvectors is not None or not vectors)):
            return P
        if P.K is None:
            P.K = self.eng.hessian(P.u, P.lam)
        P.eigenvalues, P.eigenvectors, P.eig_offset = self.eng.eigs(P.K, k, vectors=vectors)
        return P

    def eig_at(self, P, j, k):
        """The j-th smallest eigenvalue of K at P (widening the window of eigenvalues near zero)."""
        n = len(P.u)
        k = max(k, 1)
        while True:
            self._with_eigs(P, k)
            if P.eigenvalues is None or P.eig_offset is None:
                raise _StepFailure("eigenvalues (or the inertia) unavailable at a trial point")
            i = j - P.eig_offset
            if 0 <= i < len(P.eigenvalues):
                return float(P.eigenvalues[i])
            if k >= n:
                raise _StepFailure(f"eigenvalue {j} not found")
            k = min(2 * k, n)

    # ---- detection
    def detect(self, A, B, s_A, sigma_B, step, history):
        found = []
        cache = {0.0: A, float(sigma_B): B}
        kind = None
        n0 = len(self.branch.special_points)
        self._step_end = B
        try:
            fold = np.isfinite(A.t_lam) and np.isfinite(B.t_lam) and A.t_lam * B.t_lam < 0
            if self.eng.general:
                kind = "fold" if fold else "branch"
                found += self._detect_general(A, B, s_A, sigma_B, step, cache, fold)
            elif fold:
                kind = "fold"
                found += self._locate_fold(A, B, s_A, sigma_B, step, cache)
            elif A.n_negative is not None and B.n_negative is not None and A.n_negative != B.n_negative:
                kind = "branch"
                found += self._locate_crossings(A, 0.0, A, sigma_B, B, s_A, step, cache)
            kind = None
            if not found and self.n_eigs > 0 and len(history) >= 2:
                found += self._detect_dip(history + [(B, s_A + sigma_B)], step, cache, A, s_A)
        except _StepFailure as exc:
            found = list(self.branch.special_points[n0:])      # those located before the failure
            if kind is None:        # a possible (dip) point: nothing was crossed
                if self.log:
                    self.log(f"    location of a possible branch point failed: {exc}")
            else:
                # a located fold means what failed was a crossing beside it
                failed = "branch" if kind == "fold" and any(p.kind == "fold" for p in found) else kind
                found.append(self._unlocated(failed, A, B, s_A, sigma_B, step, f"its location failed: {exc}"))
        return found

    def _unlocated(self, kind, A, B, s_A, sigma_B, step, reason, crossings=None, n_before=None):
        """A special point detected in the step A → B but not located: a bracket, ``located=False``.

        Its ``parameter`` is NaN (no value to misread) and ``bracket`` the step's parameters; ``u``
        is the step's end, a converged state with the new inertia at ``info["state_parameter"]``.
        It has no critical modes (no branch switching).
        """
        n_after = B.n_negative
        n_before = A.n_negative if n_before is None else n_before
        info = {"reason": reason, "state_parameter": float(B.lam)}
        if crossings is not None:
            info["crossings"] = crossings
        p = SpecialPoint(kind=kind, parameter=math.nan, s=s_A + sigma_B, u=B.u.copy(), tangent=(B.t_u, B.t_lam),
                         eigenvalues=np.array([math.nan]) if B.eigenvalues is None else B.eigenvalues,
                         modes=np.zeros((len(B.u), 0)), multiplicity=0, n_negative_before=n_before,
                         n_negative_after=n_after, step=step, bracket=tuple(sorted((A.lam, B.lam))), located=False,
                         info=info, weights=self.eng.w, parameter_scale=self.eng.lam_scale)
        self.branch.special_points.append(p)
        if B is self._step_end:
            p.info["at_step_end"] = True        # the step's own row carries the label
        else:
            self.add_row(B, s_A + sigma_B, step, ds=sigma_B, special=p.row_label)
        if self.log:
            self.log(f"    {p.label} detected between parameters {A.lam:.8g} and {B.lam:.8g} but not located "
                     f"({reason})")
        return p

    def _illinois(self, f, a, fa, b, fb):
        """Root of f on [a, b] (fa, fb of opposite signs) by the Illinois method.

        Returns ((sigma, f, P) of the evaluated point nearest the root, (a, b) final bracket).
        """
        best = None
        side = 0
        c_prev = None
        tol = self.locate_tol
        f_scale = max(abs(fa), abs(fb))
        for _ in range(60):
            if abs(b - a) <= tol:
                break
            c = (a * fb - b * fa) / (fb - fa) if fb != fa else 0.5 * (a + b)
            lo, hi = min(a, b), max(a, b)
            if not (lo < c < hi):
                c = 0.5 * (a + b)
            elif c_prev is not None and abs(c - c_prev) <= tol:
                break                       # the estimates agree: converged (superlinearly)
            fc, Pc = f(c)
            if best is None or abs(fc) < abs(best[1]):
                best = (c, fc, Pc)
            if abs(fc) <= 1e-10 * f_scale:
                break                       # on the root: keep the sign-definite bracket
            if fc * fb > 0:
                b, fb = c, fc
                if side == -1:
                    fa *= 0.5
                side = -1
            else:
                a, fa = c, fc
                if side == +1:
                    fb *= 0.5
                side = +1
            c_prev = c
        self.last_error = abs(b - a) if c_prev is None or abs(b - a) <= tol else abs(c - c_prev)
        self.last_bracket = (a, b)
        return best, (a, b)

    def _locate_fold(self, A, B, s_A, sigma_B, step, cache):
        def f(sig):
            P = self.point_at(A, sig, 0, cache)
            return P.t_lam, P

        best, (a, b) = self._illinois(f, 0.0, A.t_lam, sigma_B, B.t_lam)
        if best is None:
            best = (sigma_B, B.t_lam, B) if abs(B.t_lam) < abs(A.t_lam) else (0.0, A.t_lam, A)
        sig, _, P = best
        lo, hi = sorted((a, b))
        P_lo, P_hi = self.point_at(A, lo, 0, cache), self.point_at(A, hi, 0, cache)
        k = max(self.n_eigs, 4)
        sp_ = self._special("fold", A, P, sig, s_A, step, k, P_lo.n_negative, P_hi.n_negative,
                            (P_lo.lam, P_hi.lam), crit=None)
        out = [sp_]
        # other crossings in the same step, on either side of the fold
        if A.n_negative is not None and P_lo.n_negative is not None and A.n_negative != P_lo.n_negative and lo > 0:
            out = self._locate_crossings(A, 0.0, A, lo, P_lo, s_A, step, cache) + out
        if P_hi.n_negative is not None and B.n_negative is not None and P_hi.n_negative != B.n_negative \
                and hi < sigma_B:
            out += self._locate_crossings(A, hi, P_hi, sigma_B, B, s_A, step, cache)
        return out

    def _locate_crossings(self, A, sa, Pa, sb, Pb, s_A, step, cache):
        """Branch points between Pa (arclength sa from A) and Pb, where the inertia changes."""
        na, nb = Pa.n_negative, Pb.n_negative
        out = []
        up = nb > na
        j = na if up else na - 1
        k = max(self.n_eigs, 4)
        located = 0
        while (up and j < nb) or (not up and j >= nb):
            if located == MAX_CROSSINGS_PER_STEP:
                # each location costs several factorisations; the first crossings are where
                # stability is lost
                rest = (nb - j) if up else (j - nb + 1)
                out.append(self._unlocated("branch", A, Pb, s_A, self.eng.dot(A.t_u, A.t_lam, Pb.u - A.u,
                                                                                 Pb.lam - A.lam), step,
                                           f"the inertia jumps from {na} to {nb} in one step; {located} crossings "
                                           f"are located, {rest} are not (a smaller ds_max resolves them)",
                                           crossings=rest, n_before=j if up else j + 1))
                break
            located += 1

            def f(sig, j=j):
                P = self.point_at(A, sig, k, cache)
                return self.eig_at(P, j, k), P

            fa = self.eig_at(Pa, j, k)
            fb = self.eig_at(Pb, j, k)
            scale = max(np.abs(Pa.K.diagonal()).max() if Pa.K is not None else 0.0,
                        np.abs(Pb.K.diagonal()).max() if Pb.K is not None else 0.0)
            if max(abs(fa), abs(fb)) <= NULL_EIG_TOL * scale:
                # a zero eigenvalue (a continuous symmetry) whose sign is round-off: not a crossing
                if self.log:
                    self.log(f"    the inertia changes between parameters {Pa.lam:.8g} and {Pb.lam:.8g} by "
                             f"an eigenvalue at round-off level ({fa:.2e}, {fb:.2e}): a null mode, ignored")
                j += 1 if up else -1
                continue
            if fa * fb > 0:
                out.append(self._unlocated("branch", A, Pb, s_A, self.eng.dot(A.t_u, A.t_lam, Pb.u - A.u,
                                                                                Pb.lam - A.lam), step,
                                           f"eigenvalue {j} does not change sign between parameters {Pa.lam:.8g} "
                                           f"and {Pb.lam:.8g} although the inertia does", n_before=j if up else j + 1))
                break
            best, (a, b) = self._illinois(f, sa, fa, sb, fb)
            if best is None:
                best = (sb, fb, Pb)
            sig, _, P = best
            lo, hi = sorted((a, b))
            P_lo = self.point_at(A, lo, k, cache) if lo > 0 else Pa
            P_hi = self.point_at(A, hi, k, cache)
            # the previous branch point may be the partner of this crossing (double eigenvalue)
            prev = self.branch.special_points[-1] if self.branch.special_points else None
            tol = self.cluster_tol * max(abs(P.lam), self.eng.lam_scale)
            if prev is not None and prev.kind == "branch" and abs(prev.parameter - P.lam) <= tol \
                    and prev.info.get("crossings", 1) < prev.multiplicity:
                prev.info["crossings"] = prev.info.get("crossings", 1) + 1
                if self.log:
                    self.log(f"    crossing at parameter {P.lam:.10g} belongs to the {prev.label} at "
                             f"{prev.parameter:.10g} (multiplicity {prev.multiplicity})")
                j += 1 if up else -1
                continue
            # eigenvalue j crosses: the inertia is j just below (j + 1 just above, downwards) by definition
            # (the bracket's ends need not be tight on both sides)
            sp_ = self._special("branch", A, P, sig, s_A, step, k, j if up else j + 1, nb,
                                (P_lo.lam, P_hi.lam), crit=j, ref=Pa if sa == 0 else P_lo)
            out.append(sp_)
            m = max(sp_.multiplicity, 1)
            # the crossings of the cluster that happen inside this bracket belong to this point; a
            # partner that crosses in a later step is merged into it there (see above)
            sp_.info["crossings"] = min(m, (nb - j) if up else (j - nb + 1))
            j += m if up else -m
        return out

    def _special(self, kind, A, P, sig, s_A, step, k, n_before, n_after, bracket, crit=None, ref=None):
        """Build a SpecialPoint at P: eigenpairs, critical mode(s), multiplicity."""
        eng = self.eng
        if eng.general:
            return self._special_general(kind, P, sig, s_A, step, bracket)
        k = max(k, 4)
        self._with_eigs(P, k, vectors=True)
        w, V, off = P.eigenvalues, P.eigenvectors, P.eig_offset
        if w is None:
            w, V, off = np.array([math.nan]), np.zeros((len(P.u), 1)), None
        # crit: a global eigenvalue index; turned into an index into the window w
        if crit is None or off is None or not 0 <= crit - off < len(w):
            crit = int(np.argmin(np.abs(w)))
        else:
            crit = crit - off
        # multiplicity: eigenvalues whose linear extrapolation (in arclength) vanishes near P
        members = [crit]
        ref = ref if ref is not None else A
        ref = self._with_eigs(ref, k)
        sig_ref = eng.dot(A.t_u, A.t_lam, ref.u - A.u, ref.lam - A.lam)
        dsig = sig - sig_ref
        lam_scale = eng.lam_scale
        tol_param = self.cluster_tol * max(abs(P.lam), lam_scale)
        if ref.eigenvalues is not None and abs(dsig) > 0 and off is not None and ref.eig_offset is not None:
            wr = {ref.eig_offset + i: v for i, v in enumerate(ref.eigenvalues)}
            slopes = [(w[i] - wr[off + i]) / dsig if off + i in wr else 0.0 for i in range(len(w))]
            dlam_dsig = (P.lam - ref.lam) / dsig if kind != "fold" else None
            for i in range(len(w)):
                if i == crit or slopes[i] == 0 or not np.isfinite(slopes[i]):
                    continue
                dist_sig = abs(w[i] / slopes[i])                      # arclength to its zero
                if kind == "fold" or dlam_dsig is None:
                    dist = dist_sig * lam_scale
                else:
                    dist = dist_sig * max(abs(dlam_dsig), 1e-300)     # in parameter units
                if dist <= tol_param:
                    members.append(i)
        members.sort()
        modes = V[:, members].copy()
        for j in range(modes.shape[1]):   # sign convention: the largest entry is positive
            if modes[np.argmax(np.abs(modes[:, j])), j] < 0:
                modes[:, j] *= -1
        if n_before is not None and n_after is not None and kind != "possible_branch":
            # the bracket ends may lie beyond other crossings: count this point's own change
            sgn = 1 if n_after > n_before else -1
            n_after = n_before + sgn * (len(members) if kind == "branch" else 1)
        info = {"eigen_index": None if off is None else off + crit, "members": members, "sigma": sig,
                "sigma_error": getattr(self, "last_error", math.nan)}
        p = SpecialPoint(kind=kind, parameter=float(P.lam), s=s_A + sig, u=P.u.copy(), tangent=(P.t_u, P.t_lam),
                         eigenvalues=w, modes=modes, multiplicity=len(members), n_negative_before=n_before,
                         n_negative_after=n_after, step=step, bracket=tuple(sorted(bracket)), info=info,
                         weights=eng.w, parameter_scale=eng.lam_scale)
        self.branch.special_points.append(p)
        self.add_row(P, s_A + sig, step, ds=sig, special=p.label)
        if self.log:
            self.log(f"    {p.summary()}")
        return p

    # ---- non-gradient problems: det J and the augmented determinant's sign (module docstring)
    @staticmethod
    def _bp_sign(P):
        """sign det [[J, g_λ], [tᵀ, 0]] = sign(det J)·sign(t_λ) at P (0 when unknown)."""
        if not P.det_sign or not np.isfinite(P.t_lam) or P.t_lam == 0:
            return 0
        return int(P.det_sign * np.sign(P.t_lam))

    def _detect_general(self, A, B, s_A, sigma_B, step, cache, fold):
        """Folds (t_λ changes sign) and branch points (τ changes sign) in the step A → B, located."""
        bp = self._bp_sign(A) * self._bp_sign(B) < 0
        if not fold:
            return self._locate_det_crossing(A, 0.0, A, sigma_B, B, s_A, step, cache) if bp else []
        out = self._locate_fold(A, B, s_A, sigma_B, step, cache)
        fold_pt = out[-1]
        lo, hi = sorted(fold_pt.info["bracket_sigma"])
        P_lo, P_hi = self.point_at(A, lo, 0, cache), self.point_at(A, hi, 0, cache)
        if lo > 0 and self._bp_sign(A) * self._bp_sign(P_lo) < 0:
            out = self._locate_det_crossing(A, 0.0, A, lo, P_lo, s_A, step, cache) + out
        if hi < sigma_B and self._bp_sign(P_hi) * self._bp_sign(B) < 0:
            out += self._locate_det_crossing(A, hi, P_hi, sigma_B, B, s_A, step, cache)
        return out

    def _psi(self, P, b, c):
        """ψ = −1/(cᵀ J⁻¹ b) at P: zero where J is singular, of the sign of det J near there."""
        eng = self.eng
        if P.K is None:
            P.K = eng.hessian(P.u, P.lam)
        fac = eng.factor(P.K)
        if fac is None:
            return 0.0
        q = float(c @ fac.solve(b))
        if not np.isfinite(q) or q == 0:
            raise _StepFailure("the branch-point test function is undefined (its border is singular)")
        return -1.0 / q

    def _locate_det_crossing(self, A, sa, Pa, sb, Pb, s_A, step, cache):
        """The branch point between Pa (arclength sa from A) and Pb where det J changes sign."""
        sigma_end = self.eng.dot(A.t_u, A.t_lam, Pb.u - A.u, Pb.lam - A.lam)
        for end in (Pb, Pa):
            b, c = self.eng.null_vector(end), self.eng.null_vector(end, transpose=True)
            if b is None or c is None:
                continue
            fa, fb = self._psi(Pa, b, c), self._psi(Pb, b, c)
            if fa * fb < 0:
                break
        else:
            return [self._unlocated("branch", A, Pb, s_A, sigma_end, step,
                                    "det J changes sign but its test function does not")]

        def f(sig):
            P = self.point_at(A, sig, 0, cache)
            return self._psi(P, b, c), P

        best, (a, b_) = self._illinois(f, sa, fa, sb, fb)
        if best is None:
            best = (sb, fb, Pb)
        sig, _, P = best
        return [self._special("branch", A, P, sig, s_A, step, 0, None, None,
                              (self.point_at(A, min(a, b_), 0, cache).lam if min(a, b_) > 0 else Pa.lam,
                               self.point_at(A, max(a, b_), 0, cache).lam))]

    def _special_general(self, kind, P, sig, s_A, step, bracket):
        """A SpecialPoint of a non-gradient problem: the null vector of J as its mode, multiplicity 1."""
        mode = self.eng.null_vector(P)
        modes = np.zeros((len(P.u), 0)) if mode is None else mode[:, None]
        info = {"sigma": sig, "sigma_error": getattr(self, "last_error", math.nan),
                "bracket_sigma": getattr(self, "last_bracket", (sig, sig))}
        p = SpecialPoint(kind=kind, parameter=float(P.lam), s=s_A + sig, u=P.u.copy(), tangent=(P.t_u, P.t_lam),
                         eigenvalues=np.zeros(0), modes=modes, multiplicity=modes.shape[1], n_negative_before=None,
                         n_negative_after=None, step=step, bracket=tuple(sorted(bracket)), info=info,
                         weights=self.eng.w, parameter_scale=self.eng.lam_scale)
        self.branch.special_points.append(p)
        self.add_row(P, s_A + sig, step, ds=sig, special=p.label)
        p.info["stability"] = None if P.stability is None else dict(P.stability)
        if self.log:
            self.log(f"    {p.summary()}")
        return p

    def _detect_dip(self, pts, step, cache, A, s_A):
        """An eigenvalue that dips towards zero at the middle of three points without a sign change."""
        (P0, s0), (P1, s1), (P2, s2) = pts[-3:]
        if any(P.eigenvalues is None for P in (P0, P1, P2)):
            return []
        if len({P0.n_negative, P1.n_negative, P2.n_negative}) != 1:
            return []
        if any(P.eig_offset is None for P in (P0, P1, P2)):
            return []
        # the eigenvalue nearest zero at the middle point, followed by its index to the others
        g = P1.eig_offset + int(np.argmin(np.abs(P1.eigenvalues)))
        vals = []
        for P in (P0, P1, P2):
            i = g - P.eig_offset
            if not 0 <= i < len(P.eigenvalues):
                return []
            vals.append(float(P.eigenvalues[i]))
        for i in [g]:
            y = np.array(vals)
            if not (np.sign(y[0]) == np.sign(y[1]) == np.sign(y[2])):
                continue
            a = np.abs(y)
            if not (a[1] < a[0] and a[1] < a[2]):
                continue
            x = np.array([s0, s1, s2]) - s1
            try:
                c2, c1, c0 = np.polyfit(x, y, 2)
            except (np.linalg.LinAlgError, ValueError):
                continue
            if c2 == 0:
                continue
            xv = -c1 / (2 * c2)
            yv = c0 - c1 * c1 / (4 * c2)
            if not (x[0] < xv < x[2]):
                continue
            if not (abs(yv) <= self.dip_tol * max(a[0], a[2]) or np.sign(yv) != np.sign(y[1])):
                continue
            # evaluate at the vertex (on the step that contains it)
            k = max(self.n_eigs, 3)
            if xv <= 0:
                base, sig, base_s, ref = P0, xv - x[0], s0, P1
            else:
                base, sig, base_s, ref = P1, xv, s1, P0
            P = self.point_at(base, sig, k, cache if base is A else {})
            kind = "possible_branch"
            p = self._special(kind, base, P, sig, base_s, step, k, P1.n_negative, P1.n_negative, (P.lam, P.lam),
                              crit=i, ref=ref)
            # rows must stay in arclength order: move the special row before B if it lies before A
            if xv <= 0:
                row = self.branch.rows.pop()
                st = self.branch.states.pop()
                pos = len(self.branch.rows) - 1  # before A's row
                self.branch.rows.insert(pos, row)
                self.branch.states.insert(pos, st)
            return [p]
        return []

