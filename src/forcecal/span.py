"""Several scans of one rig under different loads: a span of shapes per harmonic.

One scan gives each harmonic one operating deflection shape, the mix of the structure's
responses to its forces at the scan's load. When a run drives the forces in another ratio (a
second coil changed, pole gaps changed unequally, two independent magnets) its deflection is
another mix, which no single scanned shape holds: the probes then disagree with the shape and
the inertia is wrong by the part of the deflection the shape misses.

Scans of the same rig under different loads (one per coil, or per gap ratio) each give a shape
per harmonic; together they span the deflections of any load in between. :func:`merge_models`
joins the models of several scans into one whose harmonic n holds the span
{phi_n^(1), phi_n^(2), ...}; a run then solves one generalized coordinate per member it needs,
never more than the sensors allow (METHOD.md eq. 16, Nq <= NS), chosen from the probes'
residuals by an information criterion (:func:`forcecal.coordinates.choose_members`). A scan
whose shape at a harmonic is the same as the span's within the shapes' uncertainty adds
nothing there and is left out of that harmonic's span, with a note.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .basis import shape_similarity
from .errors import InputError
from .rig import Rig
from .spatial import SpatialModel

__all__ = ["SAME_SHAPE", "SCAN_FREQUENCY_TOLERANCE", "merge_models"]

SCAN_FREQUENCY_TOLERANCE = 0.01
"""Largest relative difference between the scans' fundamentals: shapes at other frequencies
belong to another dynamic response, not to the same span."""
SAME_SHAPE = 3.0
"""A scan's shape is the same as the span's when the part of it the span misses is below this
many times the shapes' own standard uncertainty (RMS over the structure)."""


def merge_models(rig: Rig, models: Sequence[SpatialModel]) -> SpatialModel:
    """One spatial model from the models of several scans of the same rig.

    Parameters
    ----------
    rig : Rig
        The rig every scan was taken on.
    models : sequence of SpatialModel
        One per scan, built by :func:`forcecal.spatial.build_spatial_model`; the first one's
        shapes are each harmonic's first member.

    Returns
    -------
    SpatialModel
        Harmonics resolved by any scan; each holds the shapes of the scans that resolve it and
        add to its span.

    Raises
    ------
    InputError
        Scans driven at different fundamentals.
    """
    first = models[0]
    if len(models) == 1:
        return first
    for m in models[1:]:
        if abs(m.f0 / first.f0 - 1.0) > SCAN_FREQUENCY_TOLERANCE:
            raise InputError(
                f"scan '{m.source}': driven at {m.f0:.6g} Hz but scan '{first.source}' at "
                f"{first.f0:.6g} Hz; the scans of one model must share the drive frequency "
                "(their shapes are the same dynamic response under different loads)")
    grid = rig.structure.grid()
    harmonics = sorted({int(n) for m in models for n in m.harmonics})
    shapes, couplings, span, span_couplings, member_scans = [], [], [], [], []
    notes = [n for m in models for n in m.notes]
    for n in harmonics:
        members = [(i, m.shapes[m.index(n)], m.couplings[m.index(n)])
                   for i, m in enumerate(models) if n in m.harmonics]
        kept = [members[0]]
        for i, fit, coupling in members[1:]:
            values = np.column_stack([f.evaluate(grid) for _, f, _ in kept])
            ratio = _novelty(values, [f.std(grid) for _, f, _ in kept], fit.evaluate(grid),
                             fit.std(grid))
            if ratio < SAME_SHAPE:
                notes.append(f"harmonic {n}: scan '{models[i].source}' adds nothing to the span "
                             f"(its shape differs from the others' by {ratio:.1f} times their "
                             "uncertainty): left out")
                continue
            kept.append((i, fit, coupling))
        shapes.append(kept[0][1])
        couplings.append(kept[0][2])
        span.append(tuple(f for _, f, _ in kept[1:]))
        span_couplings.append(np.array([c for _, _, c in kept[1:]]).T.reshape(
            len(rig.gauges), len(kept) - 1))
        member_scans.append(tuple(i for i, _, _ in kept))
        if len(kept) > 1:
            pair = shape_similarity(kept[0][1].evaluate(grid), kept[1][1].evaluate(grid))
            notes.append(f"harmonic {n}: {len(kept)} shapes (scans "
                         + ", ".join(f"'{models[i].source}'" for i, _, _ in kept)
                         + f"; MAC of the first two {pair:.4f})")
    vals = [f.evaluate(grid) for f in shapes]
    mac = np.array([[shape_similarity(a, b) for b in vals] for a in vals])
    n_snr = max(len(m.snr) for m in models)
    snr = np.max(np.stack([np.pad(m.snr, (0, n_snr - len(m.snr))) for m in models]), axis=0)
    dropped = {n: why for m in reversed(models) for n, why in m.dropped.items()
               if n not in harmonics}
    return SpatialModel(
        f0=first.f0, harmonics=np.array(harmonics), shapes=tuple(shapes),
        couplings=np.array(couplings), similarity=mac, snr=snr,
        gauge_names=first.gauge_names, dropped=dict(sorted(dropped.items())),
        n_points=sum(m.n_points for m in models), source=first.source, notes=tuple(notes),
        rig=first.rig, set_aside=first.set_aside, span=tuple(span),
        span_couplings=tuple(span_couplings), scans=tuple(m.source for m in models),
        member_scans=tuple(member_scans))


def _novelty(values: np.ndarray, stds: list[np.ndarray], new: np.ndarray,
             new_std: np.ndarray) -> float:
    """RMS of the part of ``new`` outside the span of ``values`` (least squares over the
    points), relative to the RMS of the uncertainty of that part."""
    coef, *_ = np.linalg.lstsq(values, new, rcond=None)
    miss = new - values @ coef
    var = new_std**2 + sum(abs(c) ** 2 * s**2 for c, s in zip(coef, stds, strict=True))
    return float(np.sqrt(np.mean(np.abs(miss) ** 2) / max(np.mean(var), 1e-300)))
