"""What the scan's errors do to the inertia under any drive (METHOD.md section 7, "any drive").

The inertia of a run under any drive is J_r = m_{r,1} c_r(nu) q''_1
(:mod:`forcecal.forces.transient`): the first shape's coupling, corrected at every frequency to
the operating shape of the broadband scan
(:meth:`forcecal.model.broadband.BroadbandModel.inertia_correction`). Both come from the scan,
which leaves them uncertain in three ways:

- the fitted shapes' coefficients (their covariance, :class:`forcecal.model.basis.ShapeFit`),
  which move the couplings and the shapes at the probes (drawn, as the weakest shapes are
  known to a few times their size);
- the smoothed ratios a_k / a_1 of the operating shape over frequency
  (:meth:`forcecal.model.broadband.BroadbandModel.mixing_std`), which move the correction;
- above the band, where no line was measured, the correction held at the band's top.

Each is a systematic error of the inertia's frequency response: at every frequency a factor of
known variance on the acceleration. Sample by sample, its variance is the acceleration's
short-time power weighted by it (:func:`forcecal.signals.wiener.short_time_variance`).
"""

from __future__ import annotations

import numpy as np

from ..model.broadband import BroadbandModel
from ..signals.checks import WorstHalfSecond

__all__ = ["ScanNoiseShare"]

SHAPE_DRAWS = 400
"""Draws of the shapes' coefficients (:func:`shape_error_weights`): the variance to about 7 %."""
SHAPE_SEED = 1
"""Their generator's seed."""
DRAW_BLOCK = 50
"""Draws taken at once (a 51.2 kHz record's frames hold 4097 bins)."""
SLOPE_SPAN = 0.1
"""The share of the band at its top over which the correction's slope is read."""


def correction_sensitivities(model: BroadbandModel, frequencies: np.ndarray,
                             probe_shapes: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """(n_gauges, n_shapes, n_freq) complex [1]: d c_r / d a_k, the change of every gauge's
    correction (:meth:`~forcecal.model.broadband.BroadbandModel.inertia_correction`) with each ratio
    a_k / a_1 of the operating shape (zero for the first, which is 1 by definition).

    With beta = sum_k b_k a_k, b_k = (g_1^T W G[:, k]) / (g_1^T W g_1), and c_r the correction,
    d c_r / d a_k = (m_{r,k} - c_r m_{r,1} b_k) / (beta m_{r,1}).
    """
    mix = model.mixing(frequencies)
    g1 = probe_shapes[:, 0]
    b = (g1 * weights) @ probe_shapes / ((g1 * weights) @ g1)           # (n_shapes,)
    beta = b @ mix                                                      # (n_freq,)
    m = model.couplings                                                 # (n_gauges, n_k)
    c = (m @ mix) / (beta * m[:, :1])                                   # (n_gauges, n_f)
    out = ((m[:, :, None] - c[:, None, :] * m[:, :1, None] * b[None, :, None])
           / (beta * m[:, :1])[:, None, :])
    out[:, 0] = 0.0
    return out


def shape_error_weights(model: BroadbandModel, frequencies: np.ndarray,
                        probe_shapes: np.ndarray, weights: np.ndarray,
                        basis_couplings: np.ndarray, basis_probes: np.ndarray,
                        rows: np.ndarray) -> np.ndarray:
    """(n_rows, n_freq) [kg^2]: the variance, per unit |q''_1|^2, that the fitted shapes'
    coefficients give each row of ``rows`` @ J, by Monte Carlo (GUM Supplement 1).

    At frequency nu, J_r = (m_r . a) (g_1^T W s'') / (g_1^T W G a): the couplings and the
    shapes at the probes are linear in the shapes' coefficients (through the basis's couplings
    M and its values at the probes B). ``SHAPE_DRAWS`` draws of every shape's coefficients
    from their covariance (seeded: the same for a batch and its stream); in each, the scan's
    operating shape is projected back on the drawn span, as the scan's lines are on the
    fitted one (a change within the span moves nothing), and J_r taken again (the weights'
    direction g_1 held). The span's weakest shapes are known to a few times their size,
    beyond where a first-order propagation holds: on the test beam it states 1.8-6 times the
    variance these draws find.

    Parameters
    ----------
    model : BroadbandModel
    frequencies : (n_freq,) array [Hz]
    probe_shapes : (n_probes, n_shapes) array [m]
    weights : (n_probes,) array
        The probes' inverse noise variances.
    basis_couplings : (n_gauges, n_funcs) array
        The shapes' basis's mass couplings.
    basis_probes : (n_probes, n_funcs) array
        The basis at the probes.
    rows : (n_rows, n_gauges) array
        The combinations of the gauges' inertia asked for (Psi^+'s rows, their sum).
    """
    n = min(basis_couplings.shape[1], *(len(s.coefficient_covariance) for s in model.shapes))
    span = np.column_stack([s.coefficients[:n].real for s in model.shapes])  # (n, n_k)
    g1 = probe_shapes[:, 0] * weights
    norm = g1 @ probe_shapes[:, 0]

    seen_by = g1 @ basis_probes[:, :n]                                  # (n,)
    coupled_by = rows @ basis_couplings[:, :n]                          # (r, n)

    def inertia(coeffs: np.ndarray) -> np.ndarray:              # (..., n, n_f) -> (..., r, f)
        return (coupled_by @ coeffs) * (norm / (seen_by @ coeffs))[..., None, :]

    operating = span @ model.mixing(frequencies)                        # (n, n_f)
    base = inertia(operating)
    rng = np.random.default_rng(SHAPE_SEED)
    roots = []                        # C = R R^T from its eigenvalues (a singular C serves too)
    for shape in model.shapes:
        values, vectors = np.linalg.eigh(shape.coefficient_covariance[:n, :n])
        roots.append(vectors * np.sqrt(np.clip(values, 0.0, None)))
    total = np.zeros(base.shape)
    for start in range(0, SHAPE_DRAWS, DRAW_BLOCK):    # a block at a time: memory stays small
        k = min(DRAW_BLOCK, SHAPE_DRAWS - start)
        drawn = span + np.stack([r @ rng.standard_normal((n, k)) for r in roots],
                                axis=1).transpose(2, 0, 1)              # (k, n, n_k)
        back = drawn @ (np.linalg.pinv(drawn) @ operating)              # on the drawn span
        total += np.sum(np.abs(inertia(back) - base) ** 2, axis=0)
    return total / SHAPE_DRAWS


def above_band_weights(model: BroadbandModel, frequencies: np.ndarray,
                       probe_shapes: np.ndarray, weights: np.ndarray, couplings: np.ndarray,
                       rows: np.ndarray) -> np.ndarray:
    """(n_rows, n_freq) [kg^2]: the variance, per unit |q''_1|^2, of each row of ``rows`` @ J
    above the scan's band, where no operating shape was measured and the correction is held at
    the band's top: the change its slope over the top ``SLOPE_SPAN`` of the band would make
    there, |c'(f_top) (f - f_top)|^2 (zero within the band)."""
    lo, top = model.band
    edge = np.array([top - SLOPE_SPAN * (top - lo), top])
    c = model.inertia_correction(edge, probe_shapes, weights)           # (n_g, 2)
    slope = (c[:, 1] - c[:, 0]) / (edge[1] - edge[0])                   # (n_g,)
    reach = np.clip(np.asarray(frequencies, float) - top, 0.0, None)    # (n_f,)
    return np.abs(rows @ (couplings * slope))[:, None] ** 2 * reach[None, :] ** 2


def scan_noise_weights(model: BroadbandModel, frequencies: np.ndarray,
                       probe_shapes: np.ndarray, weights: np.ndarray, couplings: np.ndarray,
                       basis_couplings: np.ndarray, basis_probes: np.ndarray,
                       rows: np.ndarray) -> np.ndarray:
    """(n_rows, n_freq) [kg^2]: the variance, per unit |q''_1|^2, of each row of ``rows`` @ J
    from the scan's noise, the part a scan that averages longer lowers: the fitted shapes'
    coefficients (:func:`shape_error_weights`) and the standard uncertainty of every ratio
    a_k / a_1, of its real and of its imaginary part, through the correction
    (:func:`correction_sensitivities`); ``couplings`` (n_gauges,) is m_{r,1}."""
    weight = shape_error_weights(model, frequencies, probe_shapes, weights, basis_couplings,
                                 basis_probes, rows)
    if model.n_shapes > 1:
        sens = correction_sensitivities(model, frequencies, probe_shapes, weights)
        per = np.einsum("cg,g,gkb->ckb", rows, couplings, sens)         # (n_rows, n_k, bins)
        weight = weight + 2.0 * np.einsum("ckb,kb->cb", np.abs(per) ** 2,
                                          model.mixing_std(frequencies) ** 2)
    return weight


def inertia_error_weights(model: BroadbandModel, frequencies: np.ndarray,
                          probe_shapes: np.ndarray, weights: np.ndarray, couplings: np.ndarray,
                          basis_couplings: np.ndarray, basis_probes: np.ndarray,
                          rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two (n_rows, n_freq) arrays [kg^2]: the variance, per unit |q''_1|^2, of each row of
    ``rows`` @ J from the scan, all of it (its noise, :func:`scan_noise_weights`, and above the
    band the correction's slope, :func:`above_band_weights`) and its noise's part alone.
    Sample by sample, the variance is q''_1's short-time power weighted by it
    (:func:`forcecal.signals.wiener.short_time_variance`)."""
    noise = scan_noise_weights(model, frequencies, probe_shapes, weights, couplings,
                               basis_couplings, basis_probes, rows)
    if model.n_shapes == 1:
        return noise, noise
    return noise + above_band_weights(model, frequencies, probe_shapes, weights, couplings,
                                      rows), noise


SCAN_NOISE_SHARE = 0.5
"""A run whose total's stated variance the scan's noise makes more than this share of, in some
half second, is noted: the scan, not the run, limits the estimate there."""


class ScanNoiseShare(WorstHalfSecond):
    """A note when the scan's noise (:func:`scan_noise_weights`) makes more than
    ``SCAN_NOISE_SHARE`` of the total force's stated variance in any half second: a scan that
    averages more periods at every point lowers it, and the run does not.

    The total's variance from the scan's noise and all its stated variance [N^2] are fed as
    they come, stacked (:meth:`add`, (2, n)); every complete half second is read once, and
    the largest share is kept.

    Parameters
    ----------
    fs : float [Hz]
    t0 : float [s]
        The time of the first sample.
    """

    limit = SCAN_NOISE_SHARE

    def _note(self, source: str, share: float, at: float) -> str:
        return (f"run '{source}': the scan's noise makes {100 * share:.0f} % of the total "
                f"force's stated variance in the half second from {at:.3g} s (its operating "
                "shapes, through the inertia): a scan that averages more periods at every "
                "point lowers it")

    def _share(self, block: np.ndarray) -> float:
        total = float(np.sum(block[1]))
        return float(np.sum(block[0])) / total if total > 0 else 0.0
