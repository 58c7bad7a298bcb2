"""The method's formulas (METHOD.md sections 2-3), each implemented once, and the structure
kinds behind one protocol."""

from __future__ import annotations

import numpy as np
import pytest

from forcecal.forces.coordinates import coordinate_map
from forcecal.forces.solve import force_solve
from forcecal.forces.steady import kept_harmonics, significant_reactions
from forcecal.model.inertia import acceleration, inertia_term, mass_weights
from forcecal.model.relaxation import force_matrix, relaxation_shapes
from forcecal.rig import parse_rig
from forcecal.structures import KINDS, Beam, Body, Plate, Structure

RNG = np.random.default_rng(11)


def complex_normal(*shape):
    return RNG.standard_normal(shape) + 1j * RNG.standard_normal(shape)


# ------------------------------------------------------------------------------ coordinates


def test_coordinate_map_recovers_coordinates_on_the_shapes():
    """Sensor phasors that lie on the shapes give back their coordinates, whatever the
    weights; one shape and a one-column span agree."""
    phi = complex_normal(5)
    w = RNG.uniform(0.5, 2.0, 5)
    gain, info = coordinate_map(phi, w)
    np.testing.assert_allclose(gain @ (phi * (0.3 - 0.7j)), 0.3 - 0.7j, rtol=1e-13)
    np.testing.assert_allclose(info, np.sum(w * np.abs(phi) ** 2), rtol=1e-13)
    gain1, info1 = coordinate_map(phi[:, None], w)
    np.testing.assert_allclose(gain1[0], gain, rtol=1e-12)
    np.testing.assert_allclose(info1[0, 0], info, rtol=1e-12)
    span = complex_normal(5, 2)
    q = np.array([1.0 + 2.0j, -0.5j])
    np.testing.assert_allclose(coordinate_map(span, w)[0] @ (span @ q), q, rtol=1e-12)


def test_coordinate_map_is_weighted_least_squares():
    """Off the shape, Q minimizes sum w |S - phi Q|^2: the residual is w-orthogonal to phi."""
    phi, s = complex_normal(6), complex_normal(6)
    w = RNG.uniform(0.5, 2.0, 6)
    q = coordinate_map(phi, w)[0] @ s
    assert abs(np.sum(w * np.conj(phi) * (s - phi * q))) < 1e-12


# ------------------------------------------------------------------------------ inertia, forces


def test_inertia_term_is_mass_coupling_times_acceleration():
    m, q, w = complex_normal(3), 0.2 + 0.1j, 2 * np.pi * 40.0
    np.testing.assert_allclose(acceleration(q, w), -(w**2) * q)
    np.testing.assert_allclose(inertia_term(m, q, w), m * (-(w**2)) * q, rtol=1e-15)
    # several shapes: J = sum_j m_j Qdd_j
    mm, qq = complex_normal(3, 2), complex_normal(2)
    np.testing.assert_allclose(inertia_term(mm, qq, w),
                               -(w**2) * (mm[:, 0] * qq[0] + mm[:, 1] * qq[1]), rtol=1e-13)
    # a map from sensor phasors to Q gives the map from sensor phasors to J
    g = complex_normal(4)
    s = complex_normal(4)
    np.testing.assert_allclose(inertia_term(m, g, w) @ s, inertia_term(m, g @ s, w),
                               rtol=1e-13)


def test_force_solve_balances_the_relaxed_gauges(beam_rig_doc):
    """Psi F = J - R with as many forces as gauges (eq. 8, 24 corrected)."""
    rig = parse_rig(beam_rig_doc)
    psi = force_matrix(rig)
    j, r = complex_normal(2, 4), complex_normal(2, 4)
    f = force_solve(np.linalg.pinv(psi), j, r)
    np.testing.assert_allclose(psi @ f, j - r, rtol=1e-12, atol=1e-12)


def test_harmonic_policy_keeps_dc_shapes_and_what_the_reactions_show():
    significant = significant_reactions(np.array([[5.0, 0.1, 3.0, 0.2, 0.4]]),
                                        np.full((1, 5), 0.1))
    np.testing.assert_array_equal(significant, [True, False, True, False, False])
    with_inertia, kept = kept_harmonics(4, [1, 3, 7], significant)
    np.testing.assert_array_equal(with_inertia, [False, True, False, True, False])
    np.testing.assert_array_equal(kept, [True, True, True, True, False])
    _, ac_kept = kept_harmonics(4, [1], np.zeros(5, dtype=bool), dc=False)
    np.testing.assert_array_equal(ac_kept, [False, True, False, False, False])


# ------------------------------------------------------------------------------ structure kinds


@pytest.fixture
def beam_rig_doc():
    return {
        "structure": {"kind": "beam", "length": 0.6, "mass_per_length": 6.0,
                      "masses": [{"x": 0.3, "mass": 0.25}]},
        "gauges": [{"name": "R1", "x": 0.0}, {"name": "R2", "x": 0.6}],
        "forces": [{"name": "F1", "x": 0.25}, {"name": "F2", "x": 0.35}],
        "sensors": [{"name": "s1", "x": 0.1}, {"name": "s2", "x": 0.5}],
    }


STRUCTURES = {
    "beam": Beam(length=0.6, mass_per_length=6.0),
    "plate": Plate(outline=((0.0, 0.0), (0.5, 0.0), (0.5, 0.3), (0.2, 0.45), (0.0, 0.3)),
                   mass_per_area=20.0),
    "body": Body(blocks=(((0.0, 0.0, 0.0), (0.4, 0.2, 0.05)),
                         ((0.4, 0.0, 0.0), (0.5, 0.1, 0.05))), density=2700.0),
}


def test_every_kind_is_registered_and_answers_the_protocol():
    assert set(KINDS) == set(STRUCTURES)
    for kind, st in STRUCTURES.items():
        assert isinstance(st, Structure) and KINDS[kind] is type(st)
        pts, masses = st.mass_quadrature()
        # mass quadrature: sum over nodes of one axis (a body's nodes enter once per axis)
        per_axis = len(masses) // (3 if st.directed else 1)
        np.testing.assert_allclose(masses[:per_axis].sum(), st.total_mass, rtol=1e-12)
        coords = st.coordinates(pts)
        assert st.rigid_modes(coords, st.frame(coords)).shape == (st.n_rigid, len(masses))
        grid = st.grid(200)
        assert all(st.contains(*np.atleast_1d(p)[:3]) for p in np.atleast_2d(grid.T).T[:20])


def test_relaxation_shapes_are_rigid_and_unit_at_their_gauge(beam_rig_doc):
    """psi_r(g_s) = delta_rs on every kind (the plate's and body's rigs from the presets)."""
    from forcecal.simulate.presets import get_preset
    from forcecal.simulate.virtual_rig import public_rig

    rigs = [parse_rig(beam_rig_doc)] + [public_rig(get_preset(p)) for p in ("plate", "body")]
    for rig in rigs:
        psi = relaxation_shapes(rig, rig.gauge_points)
        np.testing.assert_allclose(psi, np.eye(len(rig.gauges)), atol=1e-12)
        # couplings of the rigid translation along +w (beam, plate) sum to the total mass
        _, weights = mass_weights(rig)
        if not rig.structure.directed:
            np.testing.assert_allclose(weights.sum(), rig.structure.total_mass, rtol=1e-12)
