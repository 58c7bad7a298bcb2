"""Tests of forcecal.model.basis: orthonormal polynomial bases and shape fits over scan points."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from numpy.polynomial import legendre

from forcecal.errors import ConditioningError, DataError
from forcecal.model.basis import (
    column_fits,
    fit_shape,
    n_functions,
    orthonormal_basis,
    project,
    shape_similarity,
)

L = 0.8  # beam length [m]


def scan_points(n: int, rng: np.random.Generator) -> np.ndarray:
    """A jittered scan grid inside (0, L), not reaching the ends of the beam."""
    x = np.linspace(0.02, L - 0.02, n)
    return x + rng.uniform(-0.3, 0.3, n) * (x[1] - x[0])


def plate_points(rng: np.random.Generator) -> tuple[np.ndarray, tuple]:
    extent = ((0.0, 0.6), (-0.2, 0.2))
    gx, gy = np.meshgrid(np.linspace(0.01, 0.59, 12), np.linspace(-0.19, 0.19, 9))
    pts = np.column_stack([gx.ravel(), gy.ravel()]) + rng.uniform(-0.005, 0.005, (108, 2))
    return pts, extent


def test_orthonormal_on_scan_points_1d():
    rng = np.random.default_rng(0)
    x = scan_points(50, rng)
    basis = orthonormal_basis(x, (0.0, L), 15)
    b = basis.evaluate(x)
    assert b.shape == (50, 15)
    np.testing.assert_allclose(b.T @ b, np.eye(15), rtol=0, atol=1e-10)
    # weighted inner product
    w = rng.uniform(0.5, 2.0, 50)
    bw = orthonormal_basis(x, (0.0, L), 15, weights=w).evaluate(x)
    np.testing.assert_allclose(bw.T @ (w[:, None] * bw), np.eye(15), rtol=0, atol=1e-10)


def test_orthonormal_on_scan_points_2d():
    rng = np.random.default_rng(1)
    pts, extent = plate_points(rng)
    basis = orthonormal_basis(pts, extent, 7)
    b = basis.evaluate(pts)
    assert b.shape == (108, n_functions(7, 2)) == (108, 28)
    np.testing.assert_allclose(b.T @ b, np.eye(28), rtol=0, atol=1e-10)


def test_lower_orders_are_the_leading_functions():
    rng = np.random.default_rng(2)
    x = scan_points(40, rng)
    full = orthonormal_basis(x, (0.0, L), 10)
    low = orthonormal_basis(x, (0.0, L), 4)
    np.testing.assert_allclose(full.truncate(4).evaluate(x), low.evaluate(x), atol=1e-12)
    np.testing.assert_allclose(full.evaluate(x)[:, :4], low.evaluate(x), atol=1e-12)


def legendre_shape(x: np.ndarray, coef: np.ndarray) -> np.ndarray:
    return legendre.legval(2 * x / L - 1, coef)


@pytest.mark.parametrize("criterion", ["gcv", "bic"])
def test_degree5_polynomial_recovered_with_sensible_order(criterion):
    rng = np.random.default_rng(42)
    x = scan_points(80, rng)
    coef = np.array([0.2, -1.0, 0.5, 0.3, -0.4, 0.25])  # degree 5
    truth = legendre_shape(x, coef) * (1.0 - 0.5j)
    noise = 1e-3 * (rng.standard_normal(80) + 1j * rng.standard_normal(80))
    fit = fit_shape(x, truth + noise, (0.0, L), criterion=criterion)
    k = fit.basis.functions_up_to(fit.order)
    assert 6 <= k < 10 and fit.order == k
    # the basis may hold higher orders for the order's uncertainty, their coefficients zero
    assert fit.basis.n_funcs >= k and np.all(fit.coefficients[k:] == 0)
    assert fit.score.shape == fit.orders.shape
    np.testing.assert_allclose(fit.residual_std, 1e-3, rtol=0.2)
    xx = np.linspace(0, L, 301)
    err = np.abs(fit.evaluate(xx) - legendre_shape(xx, coef) * (1.0 - 0.5j))
    assert err.max() < 5e-3


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(min_value=6, max_value=40),
    order=st.integers(min_value=1, max_value=8),
    seed=st.integers(min_value=0, max_value=2**32 - 1),
    data=st.data(),
)
def test_projection_is_idempotent(n, order, seed, data):
    order = min(order, n - 1)
    rng = np.random.default_rng(seed)
    x = scan_points(n, rng)
    values = data.draw(
        hnp.arrays(float, (n, 2), elements=st.floats(-1e3, 1e3, allow_subnormal=False))
    )
    values = values[:, 0] + 1j * values[:, 1]
    # a basis orthonormal on other points: the projection must not rely on orthonormality
    basis = orthonormal_basis(np.linspace(0.0, L, 30), (0.0, L), order)
    once = project(x, values, basis)
    twice = project(x, once, basis)
    scale = np.linalg.norm(values) + 1e-300
    assert np.linalg.norm(twice - once) <= 1e-9 * scale
    # and projecting a shape already in the span changes nothing
    inside = basis.evaluate(x) @ rng.standard_normal(basis.n_funcs)
    np.testing.assert_allclose(project(x, inside, basis), inside, atol=1e-9 * np.abs(inside).max())


def test_rigid_translation_is_exact_at_order_1_and_rotation_at_order_2():
    rng = np.random.default_rng(3)
    x = scan_points(40, rng)
    translation = np.full(40, 2e-6 - 1e-6j)
    fit = fit_shape(x, translation, (0.0, L))
    assert fit.order == 1
    np.testing.assert_allclose(fit.evaluate(rng.uniform(0, L, 9)), 2e-6 - 1e-6j, rtol=1e-12)
    rotation = (3e-6 + 1e-6j) * (x - 0.3)
    fit = fit_shape(x, rotation, (0.0, L))
    assert fit.order == 2
    xx = rng.uniform(0, L, 9)
    np.testing.assert_allclose(fit.evaluate(xx), (3e-6 + 1e-6j) * (xx - 0.3), rtol=1e-11)
    # a plate: a rigid heave/pitch/roll plane is order 2 (three functions)
    pts, extent = plate_points(rng)
    plane = 1e-6 + 2e-6 * pts[:, 0] - 4e-6 * pts[:, 1]
    fit = fit_shape(pts, plane, extent)
    assert fit.order == 2 and fit.basis.functions_up_to(fit.order) == 3
    np.testing.assert_allclose(fit.evaluate(pts), plane, rtol=1e-11)


def test_evaluation_anywhere_agrees_with_the_fit_at_the_scan_points():
    rng = np.random.default_rng(4)
    x = scan_points(60, rng)
    values = np.sin(2.1 * x / L) + 0.01 * rng.standard_normal(60)
    fit = fit_shape(x, values, (0.0, L))
    np.testing.assert_allclose(fit.evaluate(x), project(x, values, fit.basis.truncate(fit.order)),
                               atol=1e-12)
    np.testing.assert_allclose(
        fit.evaluate(x[::-1][:7]), fit.evaluate(x)[::-1][:7], rtol=0, atol=1e-14
    )
    np.testing.assert_allclose(fit.evaluate(x[5]), fit.evaluate(x)[5:6], rtol=0, atol=1e-14)
    # noise-free cubic: the fit equals the polynomial between the scan points too
    cubic = legendre_shape(x, np.array([1.0, 0.5, -0.3, 0.2]))
    fit = fit_shape(x, cubic, (0.0, L))
    assert fit.order == 4
    xx = rng.uniform(0.0, L, 50)
    np.testing.assert_allclose(
        fit.evaluate(xx), legendre_shape(xx, np.array([1.0, 0.5, -0.3, 0.2])), atol=1e-12
    )


def test_first_bending_mode_fitted_to_1e_minus_3():
    rng = np.random.default_rng(5)
    x = scan_points(60, rng)
    mode = np.sin(np.pi * x / L)
    phasor = 4e-6 * np.exp(0.7j)
    noisy = phasor * mode + 4e-10 * (rng.standard_normal(60) + 1j * rng.standard_normal(60))
    fit = fit_shape(x, noisy, (0.0, L))
    xx = np.linspace(0.0, L, 401)
    rel = np.abs(fit.evaluate(xx) - phasor * np.sin(np.pi * xx / L)).max() / abs(phasor)
    assert rel < 1e-3
    assert 5 <= fit.order <= 12
    assert shape_similarity(fit.evaluate(xx), np.sin(np.pi * xx / L)) > 1 - 1e-6


def test_coefficient_covariance_matches_scatter():
    rng = np.random.default_rng(6)
    x = scan_points(40, rng)
    truth = legendre_shape(x, np.array([1.0, 0.4, -0.2]))
    sigma = 0.02
    coefs, stated = [], []
    for seed in range(200):
        noise = sigma * np.random.default_rng(1000 + seed).standard_normal(40)
        fit = fit_shape(x, truth + noise, (0.0, L), order=5)
        coefs.append(fit.coefficients)
        stated.append(np.sqrt(np.diag(fit.coefficient_covariance)))
    ratio = np.std(coefs, axis=0, ddof=1) / np.mean(stated, axis=0)
    assert np.all((ratio > 0.85) & (ratio < 1.15))
    # orthonormal design: the covariance is sigma^2 I
    np.testing.assert_allclose(np.mean(stated, axis=0), sigma, rtol=0.1)


def test_complex_values_share_one_order_with_their_real_stack():
    rng = np.random.default_rng(7)
    x = scan_points(50, rng)
    values = (1 + 2j) * np.cos(2.5 * x / L) + 0.3j * x**3 + 1e-3 * rng.standard_normal(50)
    fit_c = fit_shape(x, values, (0.0, L))
    fit_s = fit_shape(x, np.column_stack([values.real, values.imag]), (0.0, L))
    assert fit_c.order == fit_s.order
    np.testing.assert_allclose(fit_c.coefficients.real, fit_s.coefficients[:, 0], atol=1e-14)
    np.testing.assert_allclose(fit_c.coefficients.imag, fit_s.coefficients[:, 1], atol=1e-14)


def test_mac():
    rng = np.random.default_rng(8)
    a = rng.standard_normal(30) + 1j * rng.standard_normal(30)
    assert shape_similarity(a, (0.3 - 2.0j) * a) == pytest.approx(1.0, abs=1e-12)
    b = orthonormal_basis(np.linspace(0, L, 30), (0.0, L), 3).evaluate(np.linspace(0, L, 30))
    assert shape_similarity(b[:, 1], 1j * b[:, 2]) == pytest.approx(0.0, abs=1e-20)
    assert 0.0 < shape_similarity(a, a + 0.5 * rng.standard_normal(30)) < 1.0


def test_bad_inputs_raise():
    x = np.linspace(0.0, 0.8, 20)
    with pytest.raises(DataError, match="outside the extent"):
        orthonormal_basis(x * 1000, (0.0, L), 3)  # points in mm, extent in m
    with pytest.raises(DataError, match="no residual degree of freedom"):
        fit_shape(x, x, (0.0, L), max_order=20)
    with pytest.raises(ConditioningError, match="rank deficient"):
        line = np.column_stack([np.linspace(0, 0.5, 20), np.full(20, 0.1)])
        orthonormal_basis(line, ((0.0, 0.6), (-0.2, 0.2)), 3)
    with pytest.raises(DataError, match="zero shape"):
        shape_similarity(np.zeros(4), np.ones(4))


def test_covariance_carries_the_choice_of_order():
    """At a low signal-to-noise ratio the chosen order varies from draw to draw (4 to 13 here)
    and a low one truncates the shape: the covariance conditional on the chosen order alone
    understates the error of the shape at a probe-like point (RMS z 1.30); the covariance
    mixed over the orders' Akaike weights states it (RMS z 1.05 over 600 components)."""
    rng = np.random.default_rng(11)
    x = np.sort(rng.uniform(0.0, L, 40))

    def truth(p):
        return (np.sin(np.pi * p / L) + 0.3 * np.sin(2 * np.pi * p / L)
                + 0.15 * np.sin(3.3 * np.pi * p / L)) * (1 - 0.5j)

    probe = np.array([0.05 * L, 0.5 * L])
    z, z_conditional, orders = [], [], set()
    for seed in range(300):
        r = np.random.default_rng(100 + seed)
        fit = fit_shape(x, truth(x) + 0.2 * (r.standard_normal(40) + 1j * r.standard_normal(40)),
                        (0.0, L))
        err = fit.evaluate(probe) - truth(probe)
        k = fit.basis.functions_up_to(fit.order)
        conditional = np.linalg.norm(fit.basis.evaluate(probe)[:, :k], axis=1) * fit.residual_std
        z += [*(err.real / fit.std(probe)), *(err.imag / fit.std(probe))]
        z_conditional += [*(err.real / conditional), *(err.imag / conditional)]
        orders.add(fit.order)
    rms = float(np.sqrt(np.mean(np.square(z))))
    assert len(orders) >= 4
    assert 0.9 <= rms <= 1.15, rms                     # achieved 1.05
    assert np.sqrt(np.mean(np.square(z_conditional))) > 1.2   # achieved 1.30: the guard's point


def test_each_column_of_a_stack_is_known_to_its_own_residual():
    """A stack of a smooth shape (noise 0.02) and a rough pattern no smooth field fits (1.0, a
    span's junk): pooled, the smooth column's covariance takes the rough one's residual (its
    stated error 26-29 times its scatter); column by column its own (scatter / stated
    0.96-1.04 over 200 draws; the rough column's residual 0.78), the stack's order (9) and
    coefficients kept."""
    rng = np.random.default_rng(12)
    x = scan_points(40, rng)
    truth = legendre_shape(x, np.array([1.0, 0.4, -0.2]))
    rough = rng.standard_normal(40)
    coefs, stated, pooled = [], [], []
    for seed in range(200):
        noise = 0.02 * np.random.default_rng(2000 + seed).standard_normal(40)
        values = np.column_stack([truth + noise, rough])
        fit = fit_shape(x, values, (0.0, L))
        smooth, junk = column_fits(fit, x, values)
        assert smooth.order == junk.order == fit.order
        np.testing.assert_array_equal(smooth.coefficients, fit.coefficients[:, 0])
        assert 0.6 < junk.residual_std < 1.0
        k = fit.basis.functions_up_to(fit.order)
        coefs.append(smooth.coefficients[:k])
        stated.append(np.sqrt(np.diag(smooth.coefficient_covariance)[:k]))
        pooled.append(np.sqrt(np.diag(fit.coefficient_covariance)[:k]))
    k = min(len(c) for c in coefs)
    scatter = np.std([c[:k] for c in coefs], axis=0, ddof=1)
    ratio = scatter / np.mean([s[:k] for s in stated], axis=0)
    assert np.all((ratio > 0.85) & (ratio < 1.15)), ratio          # achieved 0.96-1.04
    assert np.all(np.mean([s[:k] for s in pooled], axis=0) > 10 * scatter)   # pooled: 26-29x
