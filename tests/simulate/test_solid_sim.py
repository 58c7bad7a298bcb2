"""The virtual elastic block against closed-form truths and the laws of statics.

Every check compares the model with something it does not compute itself: the dimension of the
rigid-body null space, the mass and rotary inertia of a box, a linear displacement field and
Hooke's strain energy (patch test), the Euler-Bernoulli / Timoshenko cantilever and free-free
bar, a 6-DOF rigid body on springs, and the force and moment balance of a static solve.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
import scipy.linalg

from forcecal.simulate.solid import (
    SolidModel,
    _solid_matrices,
    assemble_solid,
    clamped_dofs,
    hex8_element,
)

E, NU, RHO = 2.1e11, 0.3, 7850.0          # steel [Pa], [-], [kg/m^3]
SIZE = (0.3, 0.2, 0.05)                   # the housing block [m]
ZERO_RTOL = 1e-8                          # rigid eigenvalues relative to the first elastic one
CANTILEVER_RTOL = 0.01                    # the brief allows 3 %; 20 x 2 x 2 gives ~8e-4
LOCKED = 0.7                              # the plain trilinear brick reaches ~0.56 of the beam
FREQ_RTOL = 0.02                          # Euler-Bernoulli; 20 x 2 x 2 gives ~2.6e-3
BALANCE_RTOL = 1e-8


def centroid() -> np.ndarray:
    return np.array(SIZE) / 2


def free_model(mesh, nu=0.0, size=SIZE, masses=()):
    return assemble_solid(size, E, nu, RHO, mesh, masses=masses)


# --------------------------------------------------------------------------------------------
# rigid motion and mass


def test_free_block_has_exactly_six_stress_free_rigid_modes():
    model = assemble_solid(SIZE, E, NU, RHO, (4, 3, 2), origin=(0.1, -0.2, 0.3))
    w2 = scipy.linalg.eigvalsh(model.bending_stiffness, model.mass)
    assert np.all(np.abs(w2[:6]) < ZERO_RTOL * w2[6])
    assert w2[6] > 1e-6 * w2[-1]                         # the seventh is a genuine elastic mode
    rng = np.random.default_rng(1)
    kb = model.bending_stiffness
    for _ in range(3):
        t, theta, origin = rng.normal(size=(3, 3)) * (1e-3, 1e-2, 0.1)
        v = model.rigid_mode(t, theta, origin)
        assert np.linalg.norm(kb @ v) < 1e-13 * np.linalg.norm(kb, 2) * np.linalg.norm(v)
        # and it is the rigid field: u at the nodes is t + theta x (x - origin)
        arm = model.nodes - origin
        np.testing.assert_allclose(v.reshape(-1, 3), t + np.cross(theta, arm), rtol=1e-13,
                                   atol=1e-16)


def test_mass_and_rotary_inertia_of_the_box_with_a_point_mass():
    a, b, c = SIZE
    volume = a * b * c
    xm, ym, zm, mm = 0.07, 0.16, 0.03, 2.5                 # inside an element, off the nodes
    model = assemble_solid(SIZE, E, NU, RHO, (5, 4, 2), masses=((xm, ym, zm, mm),))
    ex = model.rigid_mode((1, 0, 0), (0, 0, 0))
    assert ex @ model.mass @ ex == pytest.approx(RHO * volume + mm, rel=1e-12)
    # rotation about z through the centroid: the trilinear basis holds this linear field
    # exactly and 2 x 2 x 2 Gauss integrates its square exactly, so the inertia is exact
    cx, cy, _ = centroid()
    rz = model.rigid_mode((0, 0, 0), (0, 0, 1), centroid())
    inertia = RHO * volume * (a**2 + b**2) / 12 + mm * ((xm - cx) ** 2 + (ym - cy) ** 2)
    assert rz @ model.mass @ rz == pytest.approx(inertia, rel=1e-12)
    # coupling of x translation and z rotation: the first moment of the point mass only
    assert ex @ model.mass @ rz == pytest.approx(-mm * (ym - cy), rel=1e-12)


# --------------------------------------------------------------------------------------------
# the element: patch test, bending and locking


def test_patch_test_reproduces_a_linear_field_and_hookes_energy():
    xs = np.array([0.0, 0.03, 0.1, 0.12])                 # unequal boxes
    ys = np.array([0.0, 0.05, 0.07, 0.15])
    zs = np.array([0.0, 0.01, 0.035, 0.04])
    kb, mm = _solid_matrices(xs, ys, zs, E, NU, RHO)
    model = SolidModel(xs, ys, zs, kb, mm, 0 * kb, kb)
    rng = np.random.default_rng(2)
    grad, shift = rng.normal(size=(3, 3)) * 1e-3, rng.normal(size=3) * 1e-4
    u = (model.nodes @ grad.T + shift).ravel()            # u(x) = A x + b
    lo, hi = model.nodes.min(axis=0), model.nodes.max(axis=0)
    inner = np.all((model.nodes > lo) & (model.nodes < hi), axis=1)
    free = (3 * np.flatnonzero(inner)[:, None] + np.arange(3)).ravel()
    fixed = np.setdiff1d(np.arange(model.n_dof), free)
    solved = np.linalg.solve(kb[np.ix_(free, free)], -kb[np.ix_(free, fixed)] @ u[fixed])
    np.testing.assert_allclose(solved, u[free], rtol=1e-10, atol=1e-12 * np.abs(u).max())
    # strain energy 2 U = V (lambda tr(eps)^2 + 2 mu eps:eps) with eps the symmetric part of A
    eps = (grad + grad.T) / 2
    lam, mu = E * NU / ((1 + NU) * (1 - 2 * NU)), E / (2 * (1 + NU))
    volume = np.prod(hi - lo)
    assert u @ kb @ u == pytest.approx(volume * (lam * np.trace(eps) ** 2
                                                 + 2 * mu * np.sum(eps**2)), rel=1e-12)


def cantilever_tip_deflection(incompatible: bool) -> tuple[float, float]:
    """(FE tip deflection, Euler-Bernoulli + Timoshenko shear) of a 0.5 x 0.04 x 0.02 bar,
    nu = 0, clamped at x = 0 with a tip load P along z as a uniform traction on the tip face."""
    length, width, height, load = 0.5, 0.04, 0.02, 100.0
    xs, ys, zs = np.linspace(0, length, 21), np.linspace(0, width, 3), np.linspace(0, height, 3)
    kb, mm = _solid_matrices(xs, ys, zs, E, 0.0, RHO, incompatible)
    model = SolidModel(xs, ys, zs, kb, mm, 0 * kb, kb)
    free = np.setdiff1d(np.arange(model.n_dof), clamped_dofs(model, 0.0))
    tip = np.flatnonzero(np.isclose(model.nodes[:, 0], length))
    # consistent nodal loads of a uniform traction on a 2 x 2 bilinear face (node order: k, j)
    weights = np.outer([0.25, 0.5, 0.25], [0.25, 0.5, 0.25]).ravel()
    f = np.zeros(model.n_dof)
    f[3 * tip + 2] = load * weights
    u = np.zeros(model.n_dof)
    u[free] = np.linalg.solve(kb[np.ix_(free, free)], f[free])
    second_moment = width * height**3 / 12
    shear = load * length / (5 / 6 * E / 2 * width * height)    # kappa = 5/6, G = E / 2
    beam = load * length**3 / (3 * E * second_moment) + shear
    return float(weights @ u[3 * tip + 2]), beam


def test_cantilever_matches_timoshenko_and_the_plain_brick_locks():
    tip, beam = cantilever_tip_deflection(incompatible=True)
    assert tip == pytest.approx(beam, rel=CANTILEVER_RTOL)
    locked, _ = cantilever_tip_deflection(incompatible=False)
    assert locked < LOCKED * beam


def test_free_free_bending_frequency_converges_to_euler_bernoulli():
    length, width, height = 0.6, 0.04, 0.012
    second_moment, area = width * height**3 / 12, width * height
    exact = 22.373 * np.sqrt(E * second_moment / (RHO * area * length**4)) / (2 * np.pi)
    errors = []
    for nx in (5, 10, 20):
        model = free_model((nx, 2, 2), size=(length, width, height))
        w2, phi = scipy.linalg.eigh(model.stiffness, model.mass, subset_by_index=[0, 6])
        bend = phi[:, 6]
        assert np.linalg.norm(bend[2::3]) > 0.99 * np.linalg.norm(bend)   # along z: thin way
        errors.append(abs(np.sqrt(w2[6]) / (2 * np.pi) / exact - 1))
    assert errors[-1] < FREQ_RTOL
    assert errors[0] > 3 * errors[1] > 9 * errors[2]      # about h^2


# --------------------------------------------------------------------------------------------
# locations


def test_row_is_exact_for_linear_fields_and_validates_locations():
    model = assemble_solid(SIZE, E, NU, RHO, (5, 4, 3), origin=(-0.1, 0.0, 0.2))
    rng = np.random.default_rng(4)
    grad, shift = rng.normal(size=(3, 3)), rng.normal(size=3)
    u = (model.nodes @ grad.T + shift).ravel()
    lo, hi = (np.array([g[end] for g in (model.xs, model.ys, model.zs)]) for end in (0, -1))
    pts = lo + rng.uniform(0, 1, size=(50, 3)) * (hi - lo)
    pts[:3] = [lo, hi, [model.xs[2], lo[1] + 0.1, lo[2] + 0.01]]   # corners, an inner face
    dirs = rng.normal(size=(50, 3))
    expected = np.sum(dirs * (pts @ grad.T + shift), axis=1) / np.linalg.norm(dirs, axis=1)
    rows = model.row(np.column_stack([pts, dirs]))
    np.testing.assert_allclose(rows @ u, expected, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(model.row([*pts[0], *(7 * dirs[0])]), rows[0], rtol=1e-15,
                               atol=1e-15)           # the direction is normalised
    for bad in (np.zeros(5), np.zeros((3, 4)), np.zeros((2, 6, 1)), [0.1, 0.1, 0, 0, 0, 0]):
        with pytest.raises(ValueError):
            model.row(bad)


# --------------------------------------------------------------------------------------------
# the block on six gauges (3-2-1)


SPRING_K = 1e6                                             # [N/m]
SPRINGS = (
    (0.05, 0.05, 0.0, 0, 0, 1, SPRING_K), (0.25, 0.05, 0.0, 0, 0, 1, SPRING_K),
    (0.15, 0.17, 0.0, 0, 0, 1, SPRING_K),                  # three under it, along z
    (0.0, 0.04, 0.025, 1, 0, 0, SPRING_K), (0.0, 0.16, 0.025, 1, 0, 0, SPRING_K),   # two along x
    (0.15, 0.0, 0.025, 0, 1, 0, SPRING_K),                 # one along y
)


@pytest.fixture(scope="module")
def mounted():
    return assemble_solid(SIZE, E, NU, RHO, (6, 4, 2), springs=SPRINGS)


def rigid_body_on_springs() -> np.ndarray:
    """w^2 of a rigid box on the springs: 6 x 6 rigid-body model about the centroid."""
    a, b, c = SIZE
    m = RHO * a * b * c
    mass = np.diag([m, m, m, m * (b**2 + c**2) / 12, m * (a**2 + c**2) / 12,
                    m * (a**2 + b**2) / 12])
    g = np.array([[*s[3:6], *np.cross(np.array(s[:3]) - centroid(), s[3:6])] for s in SPRINGS])
    return scipy.linalg.eigvalsh(SPRING_K * g.T @ g, mass)


def test_block_on_springs_has_six_rigid_body_modes_below_the_elastic_ones(mounted):
    w2 = scipy.linalg.eigvalsh(mounted.stiffness, mounted.mass, subset_by_index=[0, 6])
    w2_free = scipy.linalg.eigvalsh(mounted.bending_stiffness, mounted.mass,
                                    subset_by_index=[6, 6])
    np.testing.assert_allclose(w2[:6], rigid_body_on_springs(), rtol=1e-3)
    assert w2[5] < 1e-3 * w2_free[0]
    assert w2[6] >= w2_free[0] * (1 - 1e-12)               # the springs only stiffen


def test_static_load_is_balanced_by_the_spring_forces(mounted):
    rng = np.random.default_rng(5)
    point, direction = np.array([0.21, 0.13, 0.05]), rng.normal(size=3)
    load = 300.0 * direction / np.linalg.norm(direction)   # [N]
    u = np.linalg.solve(mounted.stiffness, 300.0 * mounted.row([*point, *direction]))
    springs = np.array(SPRINGS)
    stretch = mounted.row(springs[:, :6]) @ u
    reactions = -springs[:, 6:] * stretch[:, None] * springs[:, 3:6]   # force on the block
    np.testing.assert_allclose(reactions.sum(axis=0), -load, rtol=0,
                               atol=BALANCE_RTOL * 300.0)
    o = centroid()
    moment = np.cross(springs[:, :3] - o, reactions).sum(axis=0) + np.cross(point - o, load)
    np.testing.assert_allclose(moment, 0.0, atol=BALANCE_RTOL * 300.0 * np.linalg.norm(SIZE))
    assert np.all(np.abs(reactions).sum(axis=1) > 1.0)   # every gauge carries load


def test_assembly_is_fast_and_damping_is_stiffness_proportional():
    start = time.perf_counter()
    model = assemble_solid(SIZE, E, NU, RHO, (12, 10, 2), springs=SPRINGS, beta=1e-5)
    assert time.perf_counter() - start < 1.0
    assert model.n_dof == 3 * 13 * 11 * 3
    np.testing.assert_array_equal(model.damping, 1e-5 * model.stiffness)
    ke, me = hex8_element(E, NU, RHO, 0.025, 0.02, 0.025)
    assert ke.shape == me.shape == (24, 24)
    assert me.sum() == pytest.approx(3 * RHO * 0.025 * 0.02 * 0.025, rel=1e-13)
