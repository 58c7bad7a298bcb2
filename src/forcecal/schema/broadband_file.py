"""The broadband model file's schema (MODEL.json with ``kind`` "broadband"; INTERFACES.md
section 5): every key :meth:`forcecal.model.broadband.BroadbandModel.to_json` writes, and the
provenance ``forcecal scan`` adds beside them, declared with its type and bound, every other
key refused.

:func:`check_broadband_document` validates a decoded document against :class:`BroadbandFile`,
then checks what the declared keys cannot say alone: lists whose lengths must agree (couplings
per gauge and shape, coordinates and ratios per shape and line, a value per line), the band's
order, the lines' order, and each shape against its basis (as a spatial model's,
:mod:`.model_file`). Each fault is one line naming the file and the key
(``coordinates.re[1]``), what was found and what was expected.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import AfterValidator, Field

from ..errors import InputError
from .json_files import Faults, Finite, Matrix, NonNegative, Provenance, Table, opened
from .keys import Number, validate
from .model_file import MAX_FREQUENCY_HZ, Coupling, Shape, _check_field_shape, _rig_value

__all__ = ["check_broadband_document"]

BROADBAND_KIND = "broadband"
"""The ``kind`` a broadband model file carries (a spatial model of a steady scan has none)."""

Frequency = Annotated[float, Number(unit="Hz", ge=0.0, le=MAX_FREQUENCY_HZ)]
"""A frequency of the scan's band [Hz]."""
Band = Annotated[list[Frequency], Field(min_length=2, max_length=2)]
"""[low, high] of a band [Hz]."""


class ComplexArray(Table):
    """A complex array, its real and imaginary parts apart."""

    noun = "complex array"
    re: Matrix
    """Real parts, one row per shape of the span."""
    im: Matrix
    """Imaginary parts, as ``re``."""


class RatioModel(Table):
    """Where the ratios come from (:class:`forcecal.model.ratios.RatioChoice`)."""

    noun = "ratio model"
    source: Literal["spline", "modal"]
    """The splines' ratios or the modal model's."""
    aic_spline: Finite | None
    """The splines' Akaike criterion on the lines' own ratios (null: not scored)."""
    aic_modal: Finite | None
    """The modal model's (null: no stable pole in the band)."""
    modes: list[Annotated[list[Finite], Field(min_length=4, max_length=4)]]
    """Per mode of the modal model: natural frequency [Hz], its standard uncertainty, damping
    ratio, its standard uncertainty."""
    level_noise: NonNegative | None
    """The modal model's common level per line, relative (null without one)."""


class BroadbandFile(Table):
    """A broadband model file (MODEL.json of a scan under a broadband drive)."""

    noun = "broadband model"
    kind: Literal["broadband"]
    """What the file is."""
    band: Band
    """[low, high] of the band the shapes were measured over [Hz]."""
    shapes: Annotated[list[Shape], Field(min_length=1)]
    """The span's real shapes, strongest first (each a scalar field)."""
    couplings: Coupling
    """Each gauge's mass coupling with each shape of the span (rows: gauges)."""
    frequencies: Annotated[list[Frequency], Field(min_length=1)]
    """The lines the span was found from, ascending [Hz]."""
    coordinates: ComplexArray
    """Each line's operating shape in the span's coordinates (rows: shapes; columns: lines)."""
    singular_values: list[NonNegative]
    """Singular values of the lines scaled to unit RMS, strongest first."""
    chi2: list[NonNegative]
    """The lines' median reduced chi-square left by a span of 1, 2, ... shapes."""
    line_snr: list[NonNegative]
    """Every line's signal-to-noise ratio over the points."""
    gauge_names: Annotated[list[str], Field(min_length=1)]
    """The gauges' names."""
    n_points: int = Field(ge=0, le=10**9)
    """Scan records used."""
    source: str
    """The scan the model was built from."""
    notes: list[str]
    """What the build noted."""
    rig: dict[str, Annotated[Any, AfterValidator(_rig_value)]]
    """Flat keys of the rig the model was built for (``structure.length``, ``gauges[1].x``) to
    their number or name."""
    ratios: ComplexArray | None = None
    """The operating shape's smoothed ratios a_k / a_1 at every line (absent from a model
    written before they were kept)."""
    ratio_std: list[list[NonNegative]] | None = None
    """Their standard uncertainty, of Re and of Im each (rows: shapes; columns: lines)."""
    ratio_directions: list[list[list[Annotated[float, Field(allow_inf_nan=False)]]]] | None = None
    """Per shape, the directions over the lines of the error its ratio shares with
    neighbouring lines (the splines' smoothing), each scaled by its standard deviation (the
    first shape's none; absent: every line's error its own)."""
    ratio_model: RatioModel | None = None
    """Whether the ratios are the splines' or the modal model's, and the scores that chose
    (absent from a model written before the choice: the splines')."""
    reference_dc_a: Annotated[float, Field(allow_inf_nan=False)] | None = None
    """The scan's reference (the coil current) mean over its records [A]: the bias the
    shapes were measured under (absent where the scan's records gave none: spectra, FRFs)."""
    reference_ac_a: Annotated[float, Field(ge=0, allow_inf_nan=False)] | None = None
    """Its standard deviation about that mean, the median over the records [A]."""
    provenance: Provenance | None = None
    """Where the model comes from."""


BROADBAND_KEYS = frozenset(("band", "coordinates", "frequencies", "line_snr", "ratio_model",
                            "ratios", "singular_values"))
"""Top-level keys only a broadband model file has: a document without ``kind`` that holds one
is read as a broadband model whose ``kind`` was lost (misspelt, moved), not as a spatial one."""


def check_broadband_document(doc: Any, source: str) -> None:
    """Check a decoded broadband model file against its schema (see the module docstring).

    Parameters
    ----------
    doc : object
        What :func:`json.loads` gave (with
        :func:`forcecal.schema.json_files.object_pairs`, so that a key written twice is found).
    source : str
        The file, for the messages.

    Raises
    ------
    InputError
        ``model 'SOURCE': key 'KEY' WHAT``, naming the first key at fault.
    """
    label = f"model '{source}'"
    f = opened(doc, label, "kind", BROADBAND_KIND,
               " (a broadband model; a spatial model of a steady scan has no kind)")
    _check_broadband(f, validate(BroadbandFile, doc, label, InputError))


def _check_broadband(f: Faults, m: BroadbandFile) -> None:
    """What :class:`BroadbandFile` cannot say alone."""
    lo, hi = m.band
    if not lo < hi:
        raise f.fail("band", f"= [{lo}, {hi}]; expected [low, high] with low < high (Hz)")
    _ascending(f, m.frequencies, "frequencies")
    n_k, n_lines = len(m.shapes), len(m.frequencies)
    for k, s in enumerate(m.shapes):
        key = f"shapes[{k}]"
        _check_field_shape(f, s, key)
        # the span's shapes share one basis: a steady run mixes their coefficients
        f.count(s.coefficients_re, f"{key}.coefficients_re", len(m.shapes[0].coefficients_re),
                "values (the span's shapes share one basis, that of shapes[0])")
    f.matrix(m.couplings, "couplings", len(m.gauge_names), n_k)
    f.count(m.line_snr, "line_snr", n_lines, "values (one per line of frequencies)")
    for name, part in (("coordinates", m.coordinates), ("ratios", m.ratios)):
        if part is not None:
            f.matrix(part.re, f"{name}.re", n_k, n_lines)
            f.matrix(part.im, f"{name}.im", n_k, n_lines)
    if m.ratio_std is not None:
        f.matrix(m.ratio_std, "ratio_std", n_k, n_lines)
    if m.ratio_directions is not None:
        f.count(m.ratio_directions, "ratio_directions", n_k, "lists (one per shape)")
        for k, rows in enumerate(m.ratio_directions):
            f.matrix(rows, f"ratio_directions[{k}]", None, n_lines)
            _within_std(f, rows, None if m.ratio_std is None else m.ratio_std[k], k)


def _within_std(f: Faults, rows: Sequence[Sequence[float]], std: Sequence[float] | None,
                k: int) -> None:
    """A ratio's shared error (its directions' squares summed at a line) within its whole
    variance (``ratio_std``) at every line, to rounding: the directions are part of it."""
    if not rows:
        return
    if std is None:
        raise f.fail(f"ratio_directions[{k}]", "is given without ratio_std, of which it is part")
    shared = np.sum(np.square(np.asarray(rows, dtype=float)), axis=0)
    whole = np.square(np.asarray(std, dtype=float))
    bad = np.flatnonzero(shared > whole * (1 + 1e-6) + 1e-300)
    if bad.size:
        j = int(bad[0])
        raise f.fail(f"ratio_directions[{k}]", f"holds a variance {shared[j]:.3g} at line {j}, "
                     f"beyond its ratio's whole {whole[j]:.3g} (ratio_std[{k}][{j}] squared); "
                     "expected a part of it")


def _ascending(f: Faults, values: Sequence[float], key: str) -> None:
    """``values`` rise strictly (lines interpolated between)."""
    for j in range(1, len(values)):
        if not values[j] > values[j - 1]:
            raise f.fail(f"{key}[{j}]", f"= {values[j]!r} after {values[j - 1]!r}; expected "
                         "the lines in ascending order")
