"""A modal model of a broadband scan's coordinates: poles shared by every coordinate and line
(METHOD.md section 7, "any drive"), and the operating shape's ratios a_k / a_1 from it.

h_k(s) = sum_m [R_km / (s - p_m) + conj(R_km) / (s - conj(p_m))] + sum_j c_kj (s / w_s)^j
[+ l_k (w_s / s)^2]: a residue per coordinate and mode, upper residual terms (j = 0 .. upper)
for the modes above the band and a lower one for those below. Three steps (PolyMAX: Peeters,
Van der Auweraer, Guillaume and Leuridan, Shock and Vibration 11, 2004):

1. :func:`lscf_poles`: the least-squares complex-frequency estimator, a common denominator in
   z = exp(j w dt) over every coordinate, the numerators eliminated (real coefficients);
2. :func:`stabilisation`: its physical poles at every order up to :data:`MAX_ORDER`, stable
   where one at the order below lies within :data:`FREQUENCY_TOLERANCE` and
   :data:`DAMPING_TOLERANCE`;
3. :func:`fit_modal`: poles, residues and residual terms by maximum likelihood (Gauss-Newton),
   every line weighted by its coordinates' covariance plus a level common to every coordinate
   of the line (:attr:`ModalFit.level_noise`), and the parameters' covariance.

:func:`identify` picks the modes among the stable sets by BIC, then the residual terms.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__: list[str] = []

MAX_ORDER = 16
"""Highest order of the common denominator in the stabilisation diagram."""
FREQUENCY_TOLERANCE = 0.01
"""A pole is stable when one at the order below has its natural frequency within this share."""
DAMPING_TOLERANCE = 0.05
"""... and its damping ratio within this share."""
MAX_DAMPING = 0.2
"""Poles more damped than this are not a mode the lines resolve (computational poles)."""
MAX_MODES = 4
"""Most modes a candidate set of the diagram holds."""
MAX_UPPER = 3
"""Highest power of s among the upper residual terms tried."""
PLAUSIBLE = 1e-2
"""Residual terms are plausible while their Akaike weight is at least this share of the
best's (as a shape's order, :func:`forcecal.model.basis.order_weights`)."""
LEVEL_BOUNDS = (-6.0, 0.0)
"""log10 of the range the common level's relative standard deviation is sought in."""
LEVEL_ITERATIONS = 6
"""Alternations of the parameters' fit and the common level's at most."""
MAX_EVALUATIONS = 100
"""Gauss-Newton (Levenberg-Marquardt) steps a fit takes at most: a set that holds a pole the
data do not support wanders far longer than one that converges (a few tens)."""


@dataclass(frozen=True)
class StabilisationDiagram:
    """The physical poles of :func:`lscf_poles` at every order, and which are stable.

    Attributes
    ----------
    orders : (n_orders,) array of int
    poles : tuple of (n,) complex arrays [rad/s]
        At each order, the poles in the band (upper half-plane, damping in (0,
        :data:`MAX_DAMPING`)).
    stable : tuple of (n,) bool arrays
        Whether each has a pole at the order below within the tolerances.
    """

    orders: np.ndarray
    poles: tuple[np.ndarray, ...]
    stable: tuple[np.ndarray, ...]

    def candidates(self) -> list[np.ndarray]:
        """The distinct sets of stable poles, one per size (1 .. :data:`MAX_MODES`): the set of
        the lowest order at which that many stand stable, ascending in frequency."""
        out: dict[int, np.ndarray] = {}
        for p, s in zip(self.poles, self.stable, strict=True):
            n = int(np.count_nonzero(s))
            if 1 <= n <= MAX_MODES and n not in out:
                out[n] = np.sort_complex(p[s])
        return [out[n] for n in sorted(out)]


@dataclass(frozen=True)
class ModalFit:
    """The modal model of a set of frequency responses, and its parameters' covariance.

    Attributes
    ----------
    poles : (n_modes,) complex array [rad/s]
        One of each conjugate pair (positive imaginary part).
    residues : (n_out, n_modes) complex array [unit of h times rad/s]
    residuals : (n_out, n_terms) array [unit of h]
        Coefficients of (s / scale)^j, j = 0 .. ``upper``, then of (scale / s)^2 if ``lower``.
    upper : int
    lower : bool
    scale : float [rad/s]
        The band's top, the frequencies' scale.
    covariance : (n_params, n_params) array
        Of the parameter vector: per mode Re and Im of p / scale, then per output the
        residues' Re and Im over ``scale``, mode by mode, and the residual terms.
    level_noise : float [1]
        The relative standard deviation of a complex level common to every coordinate of a
        line (the drive's own distortion on the reference's lines: the ratios do not see it).
    chi2 : float [1]
        Of the whitened residuals.
    n_data : int
        Real values fitted (2 n_out n_lines).
    m2ll : float
        -2 log likelihood, up to a constant (chi-square plus the level's log-determinant).
    """

    poles: np.ndarray
    residues: np.ndarray
    residuals: np.ndarray
    upper: int
    lower: bool
    scale: float
    covariance: np.ndarray
    level_noise: float
    chi2: float
    n_data: int
    m2ll: float

    @property
    def n_params(self) -> int:
        """Parameters fitted (the level's standard deviation among them)."""
        return len(self.covariance) + 1

    @property
    def aic(self) -> float:
        """Akaike's criterion, -2 log L + 2 k."""
        return self.m2ll + 2.0 * self.n_params

    @property
    def bic(self) -> float:
        """Schwarz's criterion, -2 log L + k ln(n)."""
        return self.m2ll + self.n_params * float(np.log(self.n_data))

    @property
    def frequencies(self) -> np.ndarray:
        """(n_modes,) [Hz]: the undamped natural frequencies |p| / 2 pi."""
        return np.abs(self.poles) / (2.0 * np.pi)

    @property
    def damping(self) -> np.ndarray:
        """(n_modes,) [1]: the damping ratios -Re(p) / |p|."""
        return -self.poles.real / np.abs(self.poles)

    def mode_std(self) -> tuple[np.ndarray, np.ndarray]:
        """(n_modes,) [Hz] and (n_modes,) [1]: the standard uncertainties of
        :attr:`frequencies` and :attr:`damping`, by linear propagation."""
        f_std, z_std = [], []
        for m, p in enumerate(self.poles / self.scale):
            c = self.covariance[2 * m:2 * m + 2, 2 * m:2 * m + 2]
            r = abs(p)
            d_f = np.array([p.real, p.imag]) / r * self.scale / (2.0 * np.pi)
            d_z = np.array([-p.imag**2, p.real * p.imag]) / r**3
            f_std.append(np.sqrt(d_f @ c @ d_f))
            z_std.append(np.sqrt(d_z @ c @ d_z))
        return np.array(f_std), np.array(z_std)

    def residue_std(self) -> np.ndarray:
        """(n_out, n_modes) [unit of h times rad/s]: the standard uncertainty of Re and of
        Im of each residue (their mean variance)."""
        var = np.diag(self.covariance)
        n_m, n_out = len(self.poles), len(self.residues)
        per = var[2 * n_m:].reshape(n_out, -1)[:, :2 * n_m]
        return self.scale * np.sqrt((per[:, 0::2] + per[:, 1::2]) / 2.0)

    def theta(self) -> np.ndarray:
        """The parameter vector :attr:`covariance` is of."""
        p = self.poles / self.scale
        r = self.residues / self.scale
        rows = [np.column_stack([r.real, r.imag]).reshape(len(r), 2, -1).transpose(0, 2, 1)
                .reshape(len(r), -1), self.residuals]
        return np.concatenate([np.column_stack([p.real, p.imag]).ravel(),
                               np.hstack(rows).ravel()])

    def response(self, frequencies: np.ndarray) -> np.ndarray:
        """(n_out, n_freq) complex: the model at ``frequencies`` [Hz]."""
        return _model(self.theta(), self._s(frequencies), *self._sizes(), jacobian=False)[0]

    def response_jacobian(self, frequencies: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The model (n_out, n_freq) and its derivative with the parameter vector
        (n_out, n_freq, n_params), complex."""
        return _model(self.theta(), self._s(frequencies), *self._sizes(), jacobian=True)

    def ratios(self, frequencies: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The ratios h_k / h_1 at ``frequencies`` [Hz] (n_out, n_freq) complex, the first row
        1, and the standard uncertainty of Re and of Im of each (their mean variance), by
        linear propagation of :attr:`covariance`."""
        r, dr = self._ratio_jacobian(frequencies)
        var = (np.einsum("klp,pq,klq->kl", dr.real, self.covariance, dr.real)
               + np.einsum("klp,pq,klq->kl", dr.imag, self.covariance, dr.imag))
        return r, np.sqrt(np.clip(var, 0.0, None) / 2.0)

    def ratio_errors(self, frequencies: np.ndarray) -> np.ndarray:
        """(n_out, n_freq, 2 n_params): each ratio's error as a factor A over the frequencies,
        A A^T its covariance between them, of Re and of Im each (their mean), by linear
        propagation of :attr:`covariance`: the few parameters move every line's ratio at once
        (its diagonal is :meth:`ratios`' variance). A factor, not the covariance: its size
        grows with the lines, not their square."""
        _, dr = self._ratio_jacobian(frequencies)
        values, vectors = np.linalg.eigh(0.5 * (self.covariance + self.covariance.T))
        root = vectors * np.sqrt(np.clip(values, 0.0, None))               # C = root root^T
        out: np.ndarray = np.concatenate([dr.real @ root, dr.imag @ root], axis=2) / np.sqrt(2)
        return out

    def _ratio_jacobian(self, frequencies: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The ratios (n_out, n_freq) and their derivative with the parameter vector (n_out,
        n_freq, n_params), complex."""
        h, dh = self.response_jacobian(frequencies)
        r = h / h[0]
        return r, (dh - r[:, :, None] * dh[0][None]) / h[0][None, :, None]

    def _s(self, frequencies: np.ndarray) -> np.ndarray:
        return 2j * np.pi * np.asarray(frequencies, float) / self.scale

    def _sizes(self) -> tuple[int, int, int, int]:
        return len(self.poles), len(self.residues), self.upper, int(self.lower)


def _basis(s: np.ndarray, upper: int, lower: int) -> np.ndarray:
    """(n_terms, n_freq): the residual terms' functions of the scaled s."""
    rows = [s**j for j in range(upper + 1)]
    return np.array([*rows, *([1.0 / s**2] if lower else [])])


def _model(theta: np.ndarray, s: np.ndarray, n_modes: int, n_out: int, upper: int,
           lower: int, jacobian: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """The model at the scaled s, and (``jacobian``) its derivative with ``theta``."""
    m = n_modes
    per = 2 * m + upper + 1 + int(lower)
    p = theta[0:2 * m:2] + 1j * theta[1:2 * m:2]
    rest = theta[2 * m:].reshape(n_out, per)
    r = rest[:, 0:2 * m:2] + 1j * rest[:, 1:2 * m:2]
    e1 = 1.0 / (s[None, :] - p[:, None])                    # (m, n_f)
    e2 = 1.0 / (s[None, :] - p.conj()[:, None])
    b = _basis(s, upper, lower)
    h = r @ e1 + r.conj() @ e2 + rest[:, 2 * m:] @ b
    if not jacobian:
        return h, np.empty(0)
    dh = np.zeros((n_out, len(s), len(theta)), complex)
    for i in range(m):
        a, c = r[:, i, None] * e1[i] ** 2, r[:, i, None].conj() * e2[i] ** 2
        dh[:, :, 2 * i], dh[:, :, 2 * i + 1] = a + c, 1j * (a - c)
    for k in range(n_out):
        o = 2 * m + k * per
        dh[k, :, o:o + 2 * m:2] = (e1 + e2).T
        dh[k, :, o + 1:o + 2 * m:2] = (1j * (e1 - e2)).T
        dh[k, :, o + 2 * m:o + per] = b.T
    return h, dh


def lscf_poles(frequencies: np.ndarray, h: np.ndarray, std: np.ndarray,
               order: int) -> np.ndarray:
    """The poles [rad/s] of the common denominator of ``order`` fitted to every row of ``h``.

    The least-squares complex-frequency estimator: in z = exp(j w dt), dt = 1 / (2 f_top),
    h_o = N_o(z) / D(z) with real coefficients, the equation error (N_o - h_o D) / std_o
    linear in them; each output's numerator is eliminated from the normal equations
    (M = sum_o T_o - S_o^T R_o^-1 S_o), and D's highest coefficient fixed to 1.

    Parameters
    ----------
    frequencies : (n_lines,) array [Hz]
    h : (n_out, n_lines) complex array
    std : (n_out, n_lines) array
        Standard uncertainty of Re and of Im of ``h``.
    order : int
    """
    f = np.asarray(frequencies, float)
    dt = 1.0 / (2.0 * f[-1])
    basis = np.exp(2j * np.pi * f * dt)[:, None] ** np.arange(order + 1)[None, :]
    m = np.zeros((order + 1, order + 1))
    for h_o, s_o in zip(h, std, strict=True):
        x = basis / s_o[:, None]
        y = -(h_o / s_o)[:, None] * basis
        r_o, s_m, t_o = ((x.conj().T @ x).real, (x.conj().T @ y).real,
                         (y.conj().T @ y).real)
        m += t_o - s_m.T @ np.linalg.solve(r_o, s_m)
    a = np.linalg.solve(m[:order, :order], -m[:order, order])
    z = np.roots(np.append(a, 1.0)[::-1]).astype(complex)
    return np.log(z[z != 0]) / dt


def stabilisation(frequencies: np.ndarray, h: np.ndarray, std: np.ndarray,
                  max_order: int = MAX_ORDER) -> StabilisationDiagram:
    """The stabilisation diagram of :func:`lscf_poles` at orders 1 .. ``max_order``: at each,
    the physical poles (natural frequency within the lines, a line's spacing clear of either
    end; damping in (0, :data:`MAX_DAMPING`)) and whether each is stable."""
    f = np.asarray(frequencies, float)
    gap = float(np.median(np.diff(f)))
    lo, hi = 2 * np.pi * (f[0] + gap), 2 * np.pi * (f[-1] - gap)
    poles, stable = [], []
    prev = np.empty(0, complex)
    for n in range(1, max_order + 1):
        p = lscf_poles(f, h, std, n)
        wn, zeta = np.abs(p), -p.real / np.maximum(np.abs(p), np.finfo(float).tiny)
        p = p[(p.imag > 0) & (wn > lo) & (wn < hi) & (zeta > 0) & (zeta < MAX_DAMPING)]
        stable.append(np.array([_matches(q, prev) for q in p], bool))
        poles.append(p)
        prev = p
    return StabilisationDiagram(orders=np.arange(1, max_order + 1), poles=tuple(poles),
                                stable=tuple(stable))


def _matches(q: complex, others: np.ndarray) -> bool:
    """Whether a pole of ``others`` has q's natural frequency and damping within the
    tolerances."""
    if not others.size:
        return False
    wn, z = abs(q), -q.real / abs(q)
    wo, zo = np.abs(others), -others.real / np.abs(others)
    return bool(np.any((np.abs(wo - wn) <= FREQUENCY_TOLERANCE * wo)
                       & (np.abs(zo - z) <= DAMPING_TOLERANCE * zo)))


def whiteners(cov: np.ndarray, h: np.ndarray, level: float) -> np.ndarray:
    """(n_lines, n_out, n_out) complex: W_l with W_l e_l of unit variance in Re and in Im, e_l
    a line's misfit; its covariance 2 C_l + level^2 h_l h_l^H (complex), C_l ``cov`` (of Re
    and of Im each), h_l (``h``, n_out by n_lines) the line's responses."""
    c = 2.0 * np.asarray(cov, float).astype(complex)
    c += level**2 * (h.T[:, :, None] * h.T.conj()[:, None, :])
    ridge = 1e-12 * np.trace(c, axis1=1, axis2=2).real / c.shape[1]
    c += ridge[:, None, None] * np.eye(c.shape[1])
    return np.sqrt(2.0) * np.linalg.inv(np.linalg.cholesky(c))


def _stacked(w: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Re and Im of W_l x_l (x: (n_out, n_lines) or (n_out, n_lines, n_params)), stacked."""
    y = np.einsum("lij,jl...->il...", w, x)
    return np.concatenate([y.real.reshape(-1, *y.shape[2:]), y.imag.reshape(-1, *y.shape[2:])])



def fit_modal(frequencies: np.ndarray, h: np.ndarray, cov: np.ndarray, poles: np.ndarray,
              upper: int = 2, lower: bool = False, level: float | None = None) -> ModalFit:
    """The modal model with ``poles`` as start values, by maximum likelihood.

    The misfit e_l of line l (every output) has the covariance 2 C_l + s^2 h_l h_l^H
    (complex; :func:`whiteners`): the outputs' own noise and a complex level common to them
    all, of relative standard deviation s (``level``; None: estimated, alternating with the
    parameters, by least -2 log L = chi-square + 2 sum_l log(1 + s^2 h_l^H (2 C_l)^-1 h_l)).
    The parameters' covariance is (J^T J)^-1, J the whitened misfit's Jacobian, times the
    reduced chi-square where it exceeds 1.

    Parameters
    ----------
    frequencies : (n_lines,) array [Hz]
        Ascending, above 0.
    h : (n_out, n_lines) complex array
    cov : (n_lines, n_out, n_out) array
        The covariance of Re and of Im of every line's outputs.
    poles : (n_modes,) complex array [rad/s]
        Start values, positive imaginary parts.
    upper : int
        Upper residual terms s^0 .. s^upper.
    lower : bool
        A lower residual term s^-2.
    level : float, optional
        The common level's relative standard deviation, if known.
    """
    from scipy.optimize import least_squares  # on use: a steady stream starts without it

    f = np.asarray(frequencies, float)
    scale = 2.0 * np.pi * float(f[-1])
    s = 2j * np.pi * f / scale
    sizes = (len(poles), len(h), upper, int(lower))
    lev = 0.0 if level is None else float(level)
    theta = _start(s, h, whiteners(cov, h, lev), np.asarray(poles) / scale, sizes)
    for _ in range(1 if level is not None else LEVEL_ITERATIONS):
        theta = least_squares(_misfit, theta, jac=_misfit_jacobian, method="lm",
                              x_scale="jac", max_nfev=MAX_EVALUATIONS,
                              args=(s, h, whiteners(cov, h, lev), sizes)).x
        if level is not None:
            break
        new = _level(_model(theta, s, *sizes, jacobian=False)[0], h, cov)
        settled = abs(new - lev) <= 0.01 * max(new, lev, 10 ** LEVEL_BOUNDS[0])
        lev = new
        if settled:
            break
    return _result(theta, s, h, cov, sizes, lev, scale)


def _misfit(theta: np.ndarray, s: np.ndarray, h: np.ndarray, w: np.ndarray,
            sizes: tuple[int, int, int, int]) -> np.ndarray:
    return _stacked(w, h - _model(theta, s, *sizes, jacobian=False)[0])


def _misfit_jacobian(theta: np.ndarray, s: np.ndarray, h: np.ndarray, w: np.ndarray,
                     sizes: tuple[int, int, int, int]) -> np.ndarray:
    return -_stacked(w, _model(theta, s, *sizes)[1])


def _start(s: np.ndarray, h: np.ndarray, w: np.ndarray, poles: np.ndarray,
           sizes: tuple[int, int, int, int]) -> np.ndarray:
    """The parameter vector at ``poles`` (scaled), the residues and residual terms by linear
    least squares there."""
    n_m = sizes[0]
    theta = np.zeros(2 * n_m + sizes[1] * (2 * n_m + sizes[2] + 1 + sizes[3]))
    theta[0:2 * n_m:2], theta[1:2 * n_m:2] = poles.real, poles.imag
    j = _stacked(w, _model(theta, s, *sizes)[1])[:, 2 * n_m:]
    theta[2 * n_m:] = np.linalg.lstsq(j, _stacked(w, h), rcond=None)[0]
    return theta


def _level_terms(h: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """(n_lines,): h_l^H (2 C_l)^-1 h_l, what the common level's variance is scaled by."""
    x = np.linalg.solve(2.0 * np.asarray(cov, float), h.T[:, :, None])[:, :, 0]
    return np.real(np.einsum("lk,lk->l", h.T.conj(), x))


def _level(model: np.ndarray, h: np.ndarray, cov: np.ndarray) -> float:
    """The common level's relative standard deviation of least -2 log L, the model held."""
    from scipy.optimize import minimize_scalar  # on use: a steady stream starts without it

    terms = _level_terms(h, cov)

    def m2ll(log_level: float) -> float:
        lev = 10.0**log_level
        e = _stacked(whiteners(cov, h, lev), h - model)
        return float(e @ e + 2.0 * np.sum(np.log1p(lev**2 * terms)))

    found = minimize_scalar(m2ll, bounds=LEVEL_BOUNDS, method="bounded",
                            options={"xatol": 1e-3})
    return float(10.0**found.x)


def _result(theta: np.ndarray, s: np.ndarray, h: np.ndarray, cov: np.ndarray,
            sizes: tuple[int, int, int, int], level: float, scale: float) -> ModalFit:
    """The fit at ``theta``: its misfit, the parameters' covariance, the model's terms."""
    n_m, n_out, upper, lower = sizes
    w = whiteners(cov, h, level)
    e = _misfit(theta, s, h, w, sizes)
    j = _misfit_jacobian(theta, s, h, w, sizes)
    chi2 = float(e @ e)
    dof = max(e.size - len(theta), 1)
    covariance = np.linalg.pinv(j.T @ j) * max(1.0, chi2 / dof)
    rest = theta[2 * n_m:].reshape(n_out, -1)
    return ModalFit(
        poles=(theta[0:2 * n_m:2] + 1j * theta[1:2 * n_m:2]) * scale,
        residues=(rest[:, 0:2 * n_m:2] + 1j * rest[:, 1:2 * n_m:2]) * scale,
        residuals=rest[:, 2 * n_m:].copy(), upper=upper, lower=bool(lower), scale=scale,
        covariance=covariance, level_noise=level, chi2=chi2, n_data=e.size,
        m2ll=chi2 + 2.0 * float(np.sum(np.log1p(level**2 * _level_terms(h, cov)))))


def identify(frequencies: np.ndarray, h: np.ndarray, cov: np.ndarray) -> ModalFit | None:
    """The modal model of ``h`` whose modes the stabilisation diagram supports, or None when
    no pole stands stable in the band.

    Every candidate set of stable poles (:meth:`StabilisationDiagram.candidates`) is fitted
    with the upper residual terms up to s^2 (:func:`fit_modal`, each with its own common
    level) and the set of least BIC whose poles stay physical is kept; then its residual
    terms (upper 0 .. :data:`MAX_UPPER`, lower or not; the level held at the set's): the most
    that stay plausible (an Akaike weight at least :data:`PLAUSIBLE` of the best's), fitted
    again with their own level. Arguments as :func:`fit_modal`'s.
    """
    std = np.sqrt(np.diagonal(cov, axis1=1, axis2=2)).T
    sets = stabilisation(frequencies, h, std).candidates()
    fits = [fit_modal(frequencies, h, cov, poles, upper=2) for poles in sets]
    fits = [f for f in fits if _physical(f, frequencies)]
    if not fits:
        return None
    kept = min(fits, key=lambda f: f.bic)
    fits = [fit_modal(frequencies, h, cov, kept.poles, upper, lower, level=kept.level_noise)
            for upper in range(MAX_UPPER + 1) for lower in (False, True)]
    fits = [f for f in fits if _physical(f, frequencies)]
    if not fits:
        return None
    # the residual terms: the most the data make plausible (an Akaike weight not negligible),
    # not the fewest of least score, whose bias below one draw's noise the statement misses
    least = min(f.aic for f in fits)
    plausible = [f for f in fits if f.aic - least <= 2.0 * np.log(1.0 / PLAUSIBLE)]
    best = max(plausible, key=lambda f: (f.n_params, -f.aic))
    final = fit_modal(frequencies, h, cov, best.poles, best.upper, best.lower)
    # with its own level the fit can take a pole out of the lines' range or past zero
    # damping (a residual term's stand-in): the level held at the set's then stays
    return final if _physical(final, frequencies) else best


def _physical(fit: ModalFit, frequencies: np.ndarray) -> bool:
    """Whether every fitted pole is still a mode in the lines' range."""
    f = fit.frequencies
    z = fit.damping
    return bool(np.all((f > frequencies[0]) & (f < frequencies[-1]) & (z > 0)
                       & (z < MAX_DAMPING)))


def ratio_dof(fit: ModalFit, frequencies: np.ndarray, h: np.ndarray,
              cov: np.ndarray) -> float:
    """The degrees of freedom of the fit's ratios h_k / h_1 (k >= 2) as an estimator of the
    lines' own a_k / a_1: sum over them of d(fitted) / d(line's own), of Re and of Im (Ye's
    generalized degrees of freedom, the trace of a smoother's map), the fit linearized
    (Gauss-Newton) and a_1 held.

    Arguments as :func:`fit_modal`'s, the fit's own data.
    """
    s = 2j * np.pi * np.asarray(frequencies, float) / fit.scale
    w = whiteners(cov, h, fit.level_noise)
    model, dh = _model(fit.theta(), s, *fit._sizes())
    j = _stacked(w, dh)                                          # (2 n_out n_lines, P)
    gain = np.linalg.pinv(j)                                     # d theta per whitened datum
    n_out, n_lines = h.shape
    parts = gain.reshape(len(gain), 2, n_out, n_lines)
    back = parts[:, 0] - 1j * parts[:, 1]                        # Re(back . d) = gain @ [Re; Im]
    # d theta for a_kl moved by a_1l (a unit step of its ratio), complex: Re for a real step
    q = np.einsum("pil,lik,l->pkl", back, w, h[0])
    r = model / model[0]
    dr = (dh - r[:, :, None] * dh[0][None]) / model[0][None, :, None]   # (n_out, n_lines, P)
    moved_re = np.einsum("klp,pkl->kl", dr, q.real)
    moved_im = np.einsum("klp,pkl->kl", dr, -q.imag)
    return float(np.sum(moved_re.real[1:]) + np.sum(moved_im.imag[1:]))
