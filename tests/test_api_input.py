"""Bad arguments through the Python API: a ValueError from femshell naming the argument, not a numpy error."""

import numpy as np
import pytest

from femshell.growth import target_thickness
from femshell.mesh.generators import disk
from femshell.shell import Clamped, EdgeForce, EdgeMoment, Material, ShellModel, flat_rest_state
from femshell.solvers.linear import factorize


@pytest.fixture(scope="module")
def small_disk():
    return disk(radius=1.0, edge_length=0.3)


def test_thickness_per_vertex_instead_of_per_element(small_disk):
    m = small_disk
    with pytest.raises(ValueError, match=rf"one value per element \(shape \({m.n_triangles},\)\), "
                                         rf"got shape \({m.n_vertices},\)"):
        flat_rest_state(m.points, m.triangles, np.full(m.n_vertices, 0.01))
    with pytest.raises(ValueError, match=r"same shape, got \(5,\) and \(4,\)"):
        target_thickness(np.full(5, 2.0), np.ones(4))


def test_load_on_a_curve_the_mesh_does_not_have(small_disk):
    m = small_disk
    with pytest.raises(ValueError, match="mesh has no boundary curve 'inner'; it has: outer"):
        EdgeForce(m, "inner", (0.0, 0.0, 1.0))
    with pytest.raises(ValueError, match="mesh has no boundary curve 'inner'; it has: outer"):
        ShellModel(m, Material(), flat_rest_state(m.points, m.triangles, 0.01), [Clamped("outer")],
                   [EdgeMoment("inner", 1.0)])


def test_rest_state_of_another_mesh(small_disk):
    m = small_disk
    model = ShellModel(m, Material(), flat_rest_state(m.points, m.triangles, 0.01), [Clamped("outer")])
    with pytest.raises(ValueError, match=f"rest state has {m.n_triangles - 1} elements, mesh has {m.n_triangles}"):
        model.set_rest_state(flat_rest_state(m.points, m.triangles[:-1], 0.01))


def test_continuation_and_newton_arguments(small_disk):
    from femshell.shell import DeadPressure
    from femshell.solvers.continuation import LoadParameter, continuation
    from femshell.solvers.newton import NewtonError, minimize

    m = small_disk
    rest = flat_rest_state(m.points, m.triangles, 0.01)
    model = ShellModel(m, Material(), rest, [Clamped("outer")], [DeadPressure(m, 1e-6)])
    u0 = model.initial_unknowns()
    problem = LoadParameter(model)
    for kw, words in ((dict(parameter_scale=0.0), r"parameter_scale must be a finite number in \(0, inf\), got 0.0"),
                      (dict(lam_stop=np.nan), "lam_stop must be a finite number"),
                      (dict(ds=np.inf), r"ds must be a finite number in \(0, inf\)"),
                      (dict(weights=np.ones(len(u0) - 1)), f"one per unknown \\(shape \\({len(u0)},\\)\\)")):
        with pytest.raises(ValueError, match=words):
            continuation(problem, u0, 0.0, **({"ds": 0.1} | kw), log=None, max_steps=2)
    with pytest.raises(ValueError, match=f"u0 must be a vector of the problem's {len(u0)} free unknowns"):
        continuation(problem, u0[:-1], 0.0, ds=0.1, log=None)
    # a load that overflows: named, not "converged in 0 iterations, |r| = inf"
    huge = ShellModel(m, Material(), rest, [Clamped("outer")], [DeadPressure(m, 1e300)])
    with pytest.raises(NewtonError, match="the residual scale is not finite"):
        minimize(huge, u0, log=None)


def test_point_force_and_material_arguments(small_disk):
    from femshell.shell import PointForce

    m = small_disk
    with pytest.raises(ValueError, match=rf"vertices must be indices in \[0, {m.n_vertices - 1}\]"):
        PointForce(m, [m.n_vertices + 1], (0.0, 0.0, 1.0))
    with pytest.raises(ValueError, match="vertices must be indices"):
        PointForce(m, [-1], (0.0, 0.0, 1.0))            # numpy would wrap it to the last vertex
    with pytest.raises(ValueError, match="force must be 3 finite numbers"):
        PointForce(m, [0], (0.0, 1.0))
    for bad in ("1", None):
        with pytest.raises(ValueError, match="E must be a number"):
            Material(E=bad)


def test_mesh_and_chemistry_shapes(small_disk):
    from femshell.chemistry import ReactionDiffusion
    from femshell.mesh.surface import SurfaceMesh

    m = small_disk
    quads = np.array([[0, 1, 2, 3]])
    with pytest.raises(ValueError, match=r"triangles must have shape \(m, 3\), got \(1, 4\)"):
        SurfaceMesh(m.points, quads)
    with pytest.raises(ValueError, match=r"triangles must have shape \(m, 3\), got \(3, 2\)"):
        SurfaceMesh(m.points, np.array([[0, 1], [1, 2], [2, 0]]))     # was reshaped into triangles
    rd = ReactionDiffusion(m.triangles, m.n_vertices, D=0.1, beta=1.0, points=m.points, factorize=factorize)
    with pytest.raises(ValueError, match=rf"one value per vertex, shape \({m.n_vertices},\), got shape "
                                         rf"\({m.n_triangles},\)"):
        rd.step(np.zeros(m.n_vertices), 0.1, source=np.ones(m.n_triangles))


def test_chemistry_and_growth_values(small_disk):
    from femshell.chemistry import ReactionDiffusion
    from femshell.growth import contractility, stretch

    m = small_disk
    rd = ReactionDiffusion(m.triangles, m.n_vertices, D=0.1, beta=1.0, points=m.points, factorize=factorize)
    c = np.zeros(m.n_vertices)
    c[3] = -1.0
    with pytest.raises(ValueError, match="c must be >= 0 .* got min -1 at vertex 3"):
        rd.step(c, 0.1)
    for f in (contractility, stretch):
        with pytest.raises(ValueError, match="c_star .* must be a finite number, got nan"):
            f(np.zeros(3), c_star=np.nan)
        # numpy would keep the real part with only a warning
        with pytest.raises(ValueError, match=r"c must be real numbers, got complex values \(dtype complex128\)"):
            f(np.array([0.1 + 1j]))
    with pytest.raises(ValueError, match="c must be real numbers, got complex"):
        rd.step(np.ones(m.n_vertices) * (1 + 1j), 0.1)
    with pytest.raises(ValueError, match="source must be numbers, got dtype <U1"):
        rd.step(np.ones(m.n_vertices), 0.1, source="x")


def test_model_and_newton_argument_types(small_disk):
    from femshell.solvers.newton import minimize

    m = small_disk
    rest = flat_rest_state(m.points, m.triangles, 0.01)
    with pytest.raises(TypeError, match="material must be a Material, got NoneType"):
        ShellModel(m, None, rest, [Clamped("outer")])
    with pytest.raises(TypeError, match="rest must be a RestState or a thickness .*, got str"):
        ShellModel(m, Material(), "0.01", [Clamped("outer")])
    model = ShellModel(m, Material(), rest, [Clamped("outer")])
    with pytest.raises(ValueError, match=r"max_step must be a number > 0 \(or None\), got 0.0"):
        minimize(model, model.initial_unknowns(), max_step=0.0, log=None)


def test_curvature_spot_and_loop_arguments(small_disk):
    from femshell.chemistry import ReactionDiffusion
    from femshell.coupled import CoupledLoop, MechanochemicalModel, gaussian_spot
    from femshell.geometry import gaussian_curvature, mean_curvature

    m = small_disk
    eye = np.broadcast_to(np.eye(2), (4, 2, 2))
    with pytest.raises(ValueError, match=r"shape \(m, 2, 2\), got \(2, 2\) and \(2, 2\)"):
        mean_curvature(np.eye(2), np.eye(2))
    collapsed = eye.copy()
    collapsed[2] = 0.0
    for f in (mean_curvature, gaussian_curvature):
        with pytest.raises(ValueError, match="1 of 4 first fundamental forms .* first at element 2"):
            f(collapsed, eye)
    with pytest.raises(ValueError, match=r"center must be three finite numbers \(x, y, z\), got \(0, 0\)"):
        gaussian_spot(m.points, 1.0, 0.5, center=(0, 0))
    with pytest.raises(TypeError, match="mesh must be a SurfaceMesh .* got NoneType"):
        CoupledLoop(None, MechanochemicalModel())
    with pytest.raises(TypeError, match="stepping must be a TimeStepping, got dict"):
        CoupledLoop(m, MechanochemicalModel(), {"dt_max": 1.0})
    # a step too long for double precision: named, not inf or a 'rigid-body modes' pivot error
    rd = ReactionDiffusion(m.triangles, m.n_vertices, D=0.0, beta=0.0, points=m.points, factorize=factorize)
    with pytest.raises(ValueError, match="overflows c"):
        rd.step(np.ones(m.n_vertices), 1e308, source=10.0)
    rd = ReactionDiffusion(m.triangles, m.n_vertices, D=1.0, beta=0.0, points=m.points, factorize=factorize)
    with pytest.raises(ValueError, match="too long for D = 1, beta = 0"):
        rd.step(np.ones(m.n_vertices), 1e300, source=10.0)
    assert np.all(np.isfinite(rd.step(np.ones(m.n_vertices), 1.0, source=10.0)))


def test_load_magnitudes(small_disk):
    from femshell.shell import AreaLoad, DeadLoad, DeadPressure, FollowerPressure

    m = small_disk
    for make, words in ((lambda: DeadPressure(m, np.nan), "pressure must be one finite number, got nan"),
                        (lambda: DeadPressure(m, np.full(m.n_triangles, 1e-6)), "pressure must be one finite"),
                        (lambda: FollowerPressure(np.inf), "pressure must be one finite number, got inf"),
                        (lambda: AreaLoad(m, (0.0, 1e-6)), r"traction must be finite numbers of shape \(3,\)"),
                        (lambda: EdgeForce(m, "outer", (np.nan, 0, 0)), "force_per_length must be finite"),
                        (lambda: EdgeMoment("outer", "1e-3x"), "moment must be one finite number"),
                        (lambda: DeadLoad(np.zeros((4, 2))), r"shape \(n_vertices, 3\), got shape \(4, 2\)")):
        with pytest.raises(ValueError, match=words):
            make()
    assert AreaLoad(m, np.tile([0.0, 0.0, -1.0], (m.n_triangles, 1))).forces[:, 2].sum() < 0   # per triangle


def test_load_parameter_needs_loads(small_disk):
    from femshell.solvers.continuation import LoadParameter

    m = small_disk
    model = ShellModel(m, Material(), flat_rest_state(m.points, m.triangles, 0.01), [Clamped("outer")])
    with pytest.raises(ValueError, match="LoadParameter needs a model with loads"):
        LoadParameter(model)
    assert not model.load_gradient(model.initial_unknowns()).any()


def test_contradictory_or_malformed_boundary_conditions(small_disk):
    from femshell.shell import Prescribed, SimplySupported

    m = small_disk
    rest = flat_rest_state(m.points, m.triangles, 0.01)
    for bcs, words in (([Prescribed("outer", displacement=(0, 0, 0.1)), Prescribed("outer", displacement=(0, 0, -0.1))],
                        "prescribes component z of vertex .* as -0.1, but an earlier .* fixed it at 0.1"),
                       ([Clamped("outer"), Prescribed("outer", displacement=(0, 0, 0.1))], "contradictory"),
                       ([Prescribed(vertices=(-1,))], r"indices in \[0, "),
                       ([Prescribed("outer", displacement=(0, 0.1))], "displacement must be 3 finite numbers")):
        with pytest.raises(ValueError, match=words):
            ShellModel(m, Material(), rest, bcs)
    ShellModel(m, Material(), rest, [Clamped("outer"), SimplySupported("outer"), Prescribed("outer")])  # agree


def test_model_lists_and_branch_csv_path(small_disk, tmp_path):
    from femshell.io import write_branch_csv
    from femshell.solvers.continuation import LoadParameter, continuation
    from femshell.shell import DeadPressure

    m = small_disk
    rest = flat_rest_state(m.points, m.triangles, 0.01)
    with pytest.raises(TypeError, match=r"boundary_conditions must be a list, got Clamped \(write \[Clamped"):
        ShellModel(m, Material(), rest, Clamped("outer"))
    with pytest.raises(TypeError, match="loads holds a float, not a femshell load"):
        ShellModel(m, Material(), rest, [Clamped("outer")], [1e-6])
    model = ShellModel(m, Material(), rest, [Clamped("outer")], [DeadPressure(m, 1e-6)])
    b = continuation(LoadParameter(model), model.initial_unknowns(), 0.0, ds=0.5, max_steps=1, n_eigs=0,
                     detect=False, log=None)
    with pytest.raises(ValueError, match="is a directory"):
        write_branch_csv(b, tmp_path)


def test_growth_numbers(small_disk):
    from femshell.growth import element_average, stretch, target_metric, target_thickness
    from femshell.shell import uniform_growth

    m = small_disk
    for strain, words in ((np.full(m.n_triangles, 0.1), "got array"), (np.nan, "got nan"), (1e200, "got 1e")):
        with pytest.raises(ValueError, match=f"growth strain must be one number in .*{words}"):
            uniform_growth(m.points, m.triangles, 0.01, strain)
    assert uniform_growth(m.points, m.triangles, 0.01, np.asarray(0.1)).thickness.shape == (m.n_triangles,)
    with pytest.raises(ValueError, match=r"stretch s must be in \[1e-100, 1e100\]"):
        target_metric(np.broadcast_to(np.eye(2), (2, 2, 2)), np.array([1.0, 1e200]))
    with pytest.raises(ValueError, match=r"stretch s must be in \[1e-100, 1e100\]"):
        target_thickness(0.01, 1e200)
    with pytest.raises(ValueError, match="vertex values has 1 non-finite"):
        element_average(np.array([0.0, np.nan, 1.0]), np.array([[0, 1, 2]]))
    with pytest.raises(ValueError, match="lam_max must be one number"):
        stretch(0.1, lam_max=np.array([15.0, 16.0]))


def test_growth_parameter_difference_step(small_disk):
    from femshell.shell import uniform_growth
    from femshell.solvers.continuation import GrowthParameter

    m = small_disk
    model = ShellModel(m, Material(), uniform_growth(m.points, m.triangles, 0.01, 0.0), [Clamped("outer")])
    for step in (0.0, np.nan, 1.0):
        with pytest.raises(ValueError, match=r"fd_step must be in \[1e-14, 0.1\]"):
            GrowthParameter(model, lambda g: uniform_growth(m.points, m.triangles, 0.01, g), fd_step=step)


# ----------------------------------------------------------------------------- chemistry, geometry, growth, analysis

def test_reaction_diffusion_refactorises_when_D_or_beta_is_changed(small_disk):
    """Setting rd.D or rd.beta after a step used to reuse the factor of the old values (an error of 0.05)."""
    from femshell.chemistry import ReactionDiffusion

    m = small_disk
    c = np.exp(-np.sum(m.points**2, axis=1))
    for name, old, new in (("D", 1.0, 5.0), ("beta", 1.0, 3.0)):
        kw = {"D": 1.0, "beta": 1.0}
        rd = ReactionDiffusion(m.triangles, m.n_vertices, points=m.points, **kw, factorize=factorize)
        rd.step(c, 0.1)
        setattr(rd, name, new)
        fresh = ReactionDiffusion(m.triangles, m.n_vertices, points=m.points, **{**kw, name: new}, factorize=factorize)
        assert np.allclose(rd.step(c, 0.1), fresh.step(c, 0.1), rtol=1e-12, atol=1e-14)
        with pytest.raises(ValueError, match=rf"{name} must be a finite number in \[0.0, inf\), got -1"):
            setattr(rd, name, -1.0)


def test_a_negative_source_is_named_not_clipped_quietly(small_disk):
    from femshell.chemistry import ReactionDiffusion

    m = small_disk
    for D in (0.0, 1.0):
        rd = ReactionDiffusion(m.triangles, m.n_vertices, D=D, points=m.points, factorize=factorize)
        with pytest.raises(ValueError, match="source must be >= 0 with nonnegative=True .* got min -1"):
            rd.step(np.zeros(m.n_vertices), 0.1, source=-1.0)
        signed = ReactionDiffusion(m.triangles, m.n_vertices, D=D, points=m.points, nonnegative=False,
                                   factorize=factorize)
        assert signed.step(np.zeros(m.n_vertices), 0.1, source=-1.0).max() < 0


def test_curvature_source_saturates_at_infinity_and_refuses_nan_or_complex():
    from femshell.chemistry import curvature_source

    assert curvature_source(np.array([np.inf, -np.inf])).tolist() == [15.0 * 0.05, 0.0]
    for H, msg in ((np.nan, "H has 1 NaN"), (1j, "H must be real numbers")):
        with pytest.raises(ValueError, match=msg):
            curvature_source(H)
    with pytest.raises(ValueError, match="w \\(production rate\\) must be a number"):
        curvature_source(1.0, w=np.array([1.0, 2.0]))


def test_geometry_refuses_indices_outside_the_points():
    from femshell.geometry import element_to_vertex, face_normals, triangle_areas, vertex_normals

    pts = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    with pytest.raises(ValueError, match=r"negative vertex index \(-1\)"):
        triangle_areas(pts, [[0, 1, -1]])                  # numpy read -1 as the last point: area 0.5 not 0
    with pytest.raises(ValueError, match="index vertex 4 but there are only 4 points"):
        vertex_normals(pts, [[0, 1, 4]])
    with pytest.raises(ValueError, match=r"\(m, 3\) integer array"):
        face_normals(pts, [[0.0, 1.0, 2.0]])
    with pytest.raises(ValueError, match=r"one number per triangle, shape \(1,\), got \(2,\)"):
        element_to_vertex([1.0, 2.0], pts, [[0, 1, 2]])
    # no normal where there is no area: zero, not NaN
    assert np.array_equal(face_normals(np.zeros((3, 3)), [[0, 1, 2]]), np.zeros((1, 3)))
    assert np.array_equal(vertex_normals(pts, [[0, 1, 2]])[3], np.zeros(3))


def test_mean_curvature_refuses_a_negative_definite_metric():
    from femshell.geometry import mean_curvature

    with pytest.raises(ValueError, match="not positive definite"):
        mean_curvature(-np.eye(2)[None], np.eye(2)[None])


def test_growth_laws_stay_quiet_and_finite_at_the_float_range():
    import warnings

    from femshell.growth import contractility, dstretch_dc, element_average, stretch

    with warnings.catch_warnings():
        warnings.simplefilter("error")                     # an overflow warning fails here
        assert float(contractility(1e308)) == 10.0 and float(contractility(-1e308)) == 15.0
        d = dstretch_dc(np.array([-1e300, 1e300]), b=1e308)
    assert np.array_equal(d, [0.0, 0.0])                  # was NaN: -b·Δ overflowed and met σσ = 0
    with pytest.raises(ValueError, match="lam0 .* must be a finite number > 0, got True"):
        stretch(0.0, lam0=True)
    with pytest.raises(ValueError, match=r"negative vertex index \(-1\)"):
        element_average(np.ones(4), np.array([[0, 1, -1]]))


def test_pattern_measures_refuse_impossible_counts(small_disk):
    from femshell.analysis import find_spots, spot_radius, spot_spacing

    for n in (-1, 0.5):
        with pytest.raises(ValueError, match="n_spots must be an integer"):
            spot_radius(1.0, n)
    with pytest.raises(ValueError, match="area_low must be a finite number"):
        spot_spacing(10.0, np.nan, 2)
    assert np.isnan(spot_radius(0.0, 0))
    pts = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    with pytest.raises(ValueError, match="no triangles for the 3 points"):
        find_spots(pts, np.zeros((0, 3), int), np.ones(3), 0.5)
    m = small_disk
    full = find_spots(m.points, m.triangles, np.ones(m.n_vertices), 0.5)
    assert full.n_spots == 1 and 1 - 1e-12 < full.fraction_patterned <= 1.0     # a sphere gave 1 + 4e-15


def test_growth_targets_and_the_chemistry_step_name_their_bad_arguments(small_disk):
    from femshell.chemistry import ReactionDiffusion
    from femshell.growth import target_metric, target_thickness

    with pytest.raises(ValueError, match=r"rest_metric holds non-finite values in 1 element"):
        target_metric(np.array([np.eye(2), np.full((2, 2), np.nan)]), 1.0)
    with pytest.raises(ValueError, match=r"h0 must be a number or one value per element, got shape \(2, 1\)"):
        target_thickness(np.ones((2, 1)), 2.0)             # returned shape (2, 1)
    m = small_disk
    rd = ReactionDiffusion(m.triangles, m.n_vertices, points=m.points, factorize=factorize)
    for dt in (np.array([0.1, 0.2]), -1.0):
        with pytest.raises(ValueError, match="time step dt must be"):
            rd.step(np.zeros(m.n_vertices), dt)
    with pytest.raises(ValueError, match="n_vertices must be an integer >= 1, got 4.7"):
        ReactionDiffusion(m.triangles, 4.7, factorize=factorize)


def test_model_refuses_a_mesh_it_would_only_fail_on_later(small_disk):
    from femshell.mesh import SurfaceMesh
    from femshell.shell import RestState

    m = small_disk
    rest = flat_rest_state(m.points, m.triangles, 0.01)
    pts = np.array(m.points)
    pts[3, 2] = np.nan
    with pytest.raises(ValueError, match=r"mesh points hold NaN or infinity at 1 vertices \(first: 3\)"):
        ShellModel(SurfaceMesh(pts, m.triangles), Material(), rest)
    tri = np.array(m.triangles)
    tri[0] = tri[0, ::-1]                       # one triangle turned over
    with pytest.raises(ValueError, match="not consistently oriented .* fix with femshell.mesh.orient_consistently"):
        ShellModel(SurfaceMesh(m.points, tri), Material(), rest)
    # the rest state's arrays are read-only copies: an in-place edit would not reach the model's cache
    a = np.array(rest.metric)
    r2 = RestState(a, rest.curvature, rest.thickness)
    a[:] = 0.0
    assert np.all(r2.metric[:, 0, 0] > 0)
    with pytest.raises(ValueError, match="read-only"):
        r2.metric[:, 0, 0] *= 1.1
    b = np.zeros_like(a)
    b[:, 0, 1] = 0.1
    with pytest.raises(ValueError, match="target curvature must be symmetric, element 0"):
        RestState(rest.metric, b, 0.01)
