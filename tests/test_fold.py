"""Continuation through folds on a shell: the snap-through of a shallow pinned arch (issue 4).

Shallow-arch theory (femshell/validation/shallow_arch_snap.py): with e/r = 3.5 the load
λ(ξ) = (η − ξ) + ξ(η² − ξ²)/4 has an upper fold λ_max = 5.780 at ξ = a/r = +1.658 and a
lower fold λ_min = 1.220 at ξ = −1.658, one negative eigenvalue between them, and no
branch point anywhere on the path (the antisymmetric mode needs e/r > 4).
"""

from femshell.validation.shallow_arch_snap import (fold_checks, fold_theory, follow, theory_load)


def test_shallow_arch_passes_and_marks_the_folds():
    """A 42-vertex arch (20 elements along the span): continuation from λ = 0 over the snap-through
    fold, down the unstable branch, over the lower fold and up the inverted branch to a/r < -2.2."""
    xs, lam_max, lam_min = fold_theory()
    # (a target λ below λ_max would be met on the way up: stop by the rise instead)
    _, _, b = follow(0.5, lam_stop_ratio=None, callback=lambda branch, row: row["xi"] < -2.2)
    # went on past both folds, did not stop at either
    assert b.status == "callback" and b.rows[-1]["xi"] < -2.2 and b.rows[-1]["stable"]
    folds = [p for p in b.special_points if p.kind == "fold"]
    assert [p.label for p in b.special_points] == ["LP", "LP"]          # two folds, no branch point
    assert [r["special"] for r in b.rows].count("LP") == 2
    up, low = folds
    # 20 elements along the span: measured errors (validation/results/shallow-arch-snap.json, h = 0.5)
    # 0.33 % on λ_max, 1.45 % on λ_min (3.5 − 2.28: cancellation), 0.09 % / 0.04 % on ξ, 0.56 % on the
    # curve; the theory's own error (πe/L)^2 = 0.1 %. About 3x: a load 2 % off fails
    assert abs(up.parameter / lam_max - 1) < 0.01
    assert abs(low.parameter / lam_min - 1) < 0.04
    xi = {r["s"]: r["xi"] for r in b.rows if r["special"] == "LP"}
    assert abs(xi[up.s] / xs - 1) < 0.003 and abs(xi[low.s] / -xs - 1) < 0.003
    assert abs(up.tangent[1]) < 1e-3 and abs(low.tangent[1]) < 1e-3       # dλ/ds = 0 at a fold
    assert (up.n_negative_before, up.n_negative_after) == (0, 1)
    assert (low.n_negative_before, low.n_negative_after) == (1, 0)
    # the inertia: 0 before the snap-through, 1 on the unstable part, 0 on the inverted branch
    pts = [r for r in b.rows if not r["special"]]
    assert {r["n_negative"] for r in pts if r["s"] < up.s} == {0}
    between = [r for r in pts if up.s < r["s"] < low.s]
    assert between and {r["n_negative"] for r in between} == {1} and not any(r["stable"] for r in between)
    assert {r["n_negative"] for r in pts if r["s"] > low.s} == {0}
    # the unstable part really is the snap: the mid-span goes from above to below the chord
    assert max(r["xi"] for r in between) > 0 > min(r["xi"] for r in between)
    # every point lies on the theoretical load-displacement curve
    assert max(abs(r["parameter"] - float(theory_load(r["xi"]))) for r in pts) < 0.015 * lam_max
    checks, _ = fold_checks(b)
    assert checks == {"passed": True, "marked": True, "inertia": True}

