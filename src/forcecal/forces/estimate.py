"""The result of a force reconstruction: :class:`ForceEstimate`, the forces of one run with
their uncertainties, the inertia term, the reactions-only baseline and the notes, and the
views a user reads them through (a short repr, an HTML table, pandas frames)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..rig import TypeB
from .coordinates import Coordinates

__all__ = ["ForceEstimate"]


@dataclass(frozen=True)
class ForceEstimate:
    """The forces of one run.

    Attributes
    ----------
    run_name : str
        The run (its file's stem).
    force_names, gauge_names : tuple of str
        The rig's forces and gauges, in the order of the arrays' rows.
    f0 : float [Hz]
        The run's refined fundamental.
    f0_std : float [Hz]
        Its standard uncertainty.
    harmonics : (H+1,) int array
        0..H; phasors follow the convention of :mod:`forcecal.signals.harmonics`.
    force : (n_forces, H+1) complex array [N]
        The external forces' phasors.
    force_std : (n_forces, H+1) array [N]
        Their standard uncertainties (of Re and of Im each).
    total : (H+1,) complex array [N]
        The forces' sum.
    total_std : (H+1,) array [N]
        Its standard uncertainty.
    static : (n_forces, H+1) complex array [N]
        The reactions-only phasors.
    inertia : (n_gauges, H+1) complex array [N]
        The inertia term J_{r,n}.
    reactions : (n_gauges, H+1) complex array [N]
        The gauges' phasors (the tare's DC taken off).
    with_inertia : (H+1,) bool array
        Harmonics whose inertia came from the scan model.
    kept : (H+1,) bool array
        Harmonics the data support (a shape in the model, or reactions above five times
        their noise); the others are set to zero.
    coordinates : Coordinates
        The generalized coordinates of every harmonic's span.
    time : (n_samples,) array [s]
        The run's sample times.
    series : (n_forces, n_samples) array [N]
        The forces sample by sample.
    static_series : (n_forces, n_samples) array [N]
        -Psi^+ R(t) sample by sample.
    psi_condition : float
        Condition number of the force matrix Psi.
    consistency : (H+1,) array [N]
        |Psi f - (J - R)| per harmonic: the force solve's residual (nonzero with more gauges
        than forces).
    combination_names : tuple of str
        Every force, the total and the resultant's first moments
        (:func:`forcecal.forces.uncertainty.combinations`).
    combination, combination_std : (n_c, H+1) arrays [N, N m]
        Their phasors and standard uncertainties: the noise and the type-B parts combined,
        of Re and of Im pooled (the DC's own for n = 0).
    combination_std_re_im : (n_c, H+1, 2) array [N, N m] or None
        The same, of Re and of Im apart: a sensitivity or a mass scales a phasor, so its part
        lies along the phasor (a phasor along Re has its type-B error on Re, up to sqrt(2)
        times the pooled value).
    dc_observed : bool
        False for AC-coupled gauges (the DC is not estimated).
    notes : tuple of str
        What the estimate noticed (self-checks, defaults, limits).
    budget : dict of str to (n_c, H+1) array [N, N m]
        Each source's standard uncertainty in every combination and harmonic (noise: gauges,
        probes and shapes, unresolved harmonics; type B: :data:`forcecal.forces.budget.SOURCES`);
        their root sum of squares is ``combination_std``.
    type_b : TypeB or None
        The rig's type-B standard uncertainties the budget used.
    monte_carlo_std : (n_c, H+1) array [N, N m] or None
        The standard deviation of a Monte Carlo over the sources
        :data:`forcecal.forces.budget.MONTE_CARLO_SOURCES` (None without one).
    monte_carlo_draws : int
        Its number of draws (0 without one).
    """

    run_name: str
    force_names: tuple[str, ...]
    gauge_names: tuple[str, ...]
    f0: float
    harmonics: np.ndarray
    force: np.ndarray
    force_std: np.ndarray
    total: np.ndarray
    total_std: np.ndarray
    static: np.ndarray
    inertia: np.ndarray
    reactions: np.ndarray
    with_inertia: np.ndarray
    kept: np.ndarray
    coordinates: Coordinates
    time: np.ndarray
    series: np.ndarray
    static_series: np.ndarray
    psi_condition: float
    consistency: np.ndarray
    f0_std: float = 0.0
    combination_names: tuple[str, ...] = ()
    combination: np.ndarray | None = None
    combination_std: np.ndarray | None = None
    combination_std_re_im: np.ndarray | None = None
    dc_observed: bool = True
    notes: tuple[str, ...] = field(default=())
    budget: dict[str, np.ndarray] = field(default_factory=dict)
    type_b: TypeB | None = None
    monte_carlo_std: np.ndarray | None = None
    monte_carlo_draws: int = 0

    @property
    def total_series(self) -> np.ndarray:
        """(n_samples,) [N]"""
        return self.series.sum(axis=0)

    @property
    def inertia_share(self) -> float:
        """RMS of the inertia's contribution to the total AC force over the RMS of that force."""
        inertia_total = np.sum(self.inertia_force[:, 1:], axis=0)
        return float(np.sqrt(np.sum(np.abs(inertia_total) ** 2))
                     / np.sqrt(np.sum(np.abs(self.total[1:]) ** 2)))

    @property
    def inertia_force(self) -> np.ndarray:
        """(n_forces, H+1) complex [N]: the inertia's contribution Psi^+ J_n to each force."""
        return self.force - self.static

    def expanded(self, k: float = 2.0) -> np.ndarray:
        """(n_c, H+1) [N, N m]: expanded uncertainties k u of every combination and harmonic
        (k = 2: about 95 % coverage for a normal distribution)."""
        assert self.combination_std is not None
        out: np.ndarray = k * self.combination_std
        return out

    @property
    def waveform_std(self) -> float:
        """Standard uncertainty [N] of the total force waveform (RMS over the record, AC part).

        The phasors' uncertainties, plus the fundamental's: an error df in f0 turns harmonic n
        by 2 pi n df (t - t_mid), whose mean square over a record of duration T is
        (2 pi n df)^2 T^2 / 12.
        """
        n = self.harmonics[1:]
        duration = self.time[-1] - self.time[0] if self.time.size > 1 else 0.0
        drift = (2 * np.pi * n * self.f0_std * duration) ** 2 / 12 * np.abs(self.total[1:]) ** 2 / 2
        return float(np.sqrt(np.sum(self.total_std[1:] ** 2) + np.sum(drift)))

    def _fundamentals(self) -> list[tuple[str, float, float, float]]:
        """(name, |F_1|, its std, reactions-only |F_1|) [N] of every force and the total."""
        if self.force.shape[1] < 2:
            return []
        f, std, st = (np.vstack([a, a.sum(axis=0)]) for a in (self.force, self.force_std,
                                                              self.static))
        std[-1] = self.total_std
        return [(name, float(abs(f[k, 1])), float(std[k, 1]), float(abs(st[k, 1])))
                for k, name in enumerate((*self.force_names, "total"))]

    def __repr__(self) -> str:
        """One line: the run, its fundamental, every force's |F_1| with std, the inertia share."""
        amps = ", ".join(f"{name} {a:.4g} ± {s:.2g}" for name, a, s, _ in self._fundamentals())
        return (f"ForceEstimate(run '{self.run_name}', f0 = {self.f0:.6g} Hz, "
                f"|F_1| [N]: {amps or 'none'}; inertia share {self._share()})")

    def _share(self) -> str:
        return f"{100 * self.inertia_share:.1f} %" if np.any(self.total[1:]) else "n/a"

    def _repr_html_(self) -> str:
        """A small table for notebooks: per force, |F_1| with std and the reactions-only one."""
        from html import escape

        rows = "".join(f"<tr><td>{escape(n)}</td><td>{a:.4g}</td><td>{s:.2g}</td>"
                       f"<td>{r:.4g}</td></tr>" for n, a, s, r in self._fundamentals())
        return (f"<p><b>ForceEstimate</b> of run '{escape(self.run_name)}': f<sub>0</sub> = "
                f"{self.f0:.6g} Hz, inertia share {self._share()}</p><table><tr><th>force</th>"
                "<th>|F<sub>1</sub>| [N]</th><th>std [N]</th>"
                f"<th>reactions only [N]</th></tr>{rows}</table>")

    @staticmethod
    def _pandas() -> Any:
        import pandas  # type: ignore[import-untyped]  # imported on use only

        return pandas

    def to_dataframe(self) -> Any:
        """The force series as a pandas DataFrame: index ``time`` [s], one column per force,
        ``total``, and the reactions-only ones with suffix ``_static`` [N] (the columns of
        ``NAME.forces.csv``). Example: ``est.to_dataframe()[["total", "total_static"]]``."""
        pd = self._pandas()
        names = (*self.force_names, "total")
        values = np.vstack([self.series, self.total_series, self.static_series,
                            self.static_series.sum(axis=0)])
        columns = [*names, *(f"{n}_static" for n in names)]
        return pd.DataFrame(values.T, columns=columns, index=pd.Index(self.time, name="time"))

    def harmonics_frame(self) -> Any:
        """Every force's harmonics as a pandas DataFrame, index (``force``, ``harmonic``):
        ``amplitude`` |F_n| [N], ``phase`` [rad], ``std`` [N] (of Re and of Im),
        ``static_amplitude`` (reactions only) [N], ``with_inertia``, ``kept`` (bool).
        Example: ``est.harmonics_frame().loc["F1", "amplitude"]``."""
        pd = self._pandas()
        n_f = len(self.force_names)
        index = pd.MultiIndex.from_product(
            [list(self.force_names), [int(n) for n in self.harmonics]], names=["force", "harmonic"])
        return pd.DataFrame({
            "amplitude": np.abs(self.force).ravel(), "phase": np.angle(self.force).ravel(),
            "std": self.force_std.ravel(), "static_amplitude": np.abs(self.static).ravel(),
            "with_inertia": np.tile(self.with_inertia.astype(bool), n_f),
            "kept": np.tile(self.kept.astype(bool), n_f)}, index=index)
