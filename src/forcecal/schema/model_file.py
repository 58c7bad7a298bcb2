"""The spatial model file's schema (MODEL.json, format "forcecal spatial model 1";
INTERFACES.md section 5): every key :meth:`forcecal.model.spatial.SpatialModel.to_json` writes,
declared with its type and bound, every other key refused.

:func:`check_model_document` validates a decoded document against :class:`ModelFile`, then
checks what the declared keys cannot say alone: lists whose lengths must agree (one shape per
harmonic, couplings per harmonic and gauge, a shape's basis and coefficients per basis
function), a covariance, a shape's uncertainty against its size, the multi-scan span's entries
against the harmonics. Each fault is one line naming the file and the key
(``shapes[1].order``), what was found and what was expected.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

from pydantic import AfterValidator, Discriminator, Field, Tag

from ..errors import InputError
from ..model._orthonormal_basis import FAMILIES, n_functions
from .json_files import (
    MAX_NUMBER,
    Faults,
    Finite,
    Matrix,
    NonNegative,
    Provenance,
    Table,
    opened,
    short,
)
from .keys import Number, validate

__all__ = ["check_model_document"]

MODEL_FORMAT = "forcecal spatial model 1"
"""The ``format`` a spatial model file carries."""
MAX_ORDER = 64
"""Highest shape order (functions per axis) a model may hold; ``forcecal scan`` picks < 30."""
MAX_HARMONIC = 1000
"""Highest harmonic number of a model."""
MAX_FREQUENCY_HZ = 1e6
MAX_COUPLING = 1e6
"""kg m: a mass coupling beyond is not a laboratory structure's."""
MAX_RELATIVE_STD = 100.0
"""A shape coefficient's standard deviation may reach this many times the norm of the shape's
coefficients (or its residual's standard deviation, if larger): a broadband span's weakest
shape is known to about 4 times its size, a steady scan's weakest harmonic to its size."""

Coupling = list[list[Annotated[float, Number(ge=-MAX_COUPLING, le=MAX_COUPLING)]]]
Coefficient = Annotated[float, Number(ge=-1e3, le=1e3)]
Bound = Annotated[float, Number(ge=-1e4, le=1e4)]
Interval = Annotated[list[Bound], Field(min_length=2, max_length=2)]


def _family(name: str) -> str:
    if name not in FAMILIES:
        raise ValueError(f"= {name!r}; expected one of {', '.join(FAMILIES)}")
    return name


def _rig_value(value: Any) -> Any:
    if isinstance(value, bool) or not isinstance(value, str | int | float):
        raise ValueError(f"must be a number or a name, found {short(value)}")
    if not isinstance(value, str) and not (math.isfinite(value) and abs(value) <= MAX_NUMBER):
        raise ValueError(f"= {short(value)} must be a finite number (at most {MAX_NUMBER:g})")
    return value


class Shape(Table):
    """A harmonic's shape over the structure: an orthonormal polynomial basis and its
    coefficients."""

    noun = "shape"
    order: int = Field(ge=1, le=MAX_ORDER)
    """Functions per axis the shape uses (chosen by its criterion)."""
    basis_order: int | None = Field(None, ge=1, le=MAX_ORDER)
    """Functions per axis of the basis, when above ``order``."""
    criterion: str
    """How the order was chosen: "gcv" or "bic"."""
    domain: Annotated[list[Interval], Field(min_length=1, max_length=3)]
    """[lo, hi] per axis of the structure the basis is orthonormal over [m]."""
    family: Annotated[str, AfterValidator(_family)] = "legendre"
    """The basis's family of raw functions."""
    basis: Matrix
    """Orthonormalization: the raw functions' coefficients of each basis function."""
    columns: Annotated[list[Annotated[int, Field(ge=0)]], Field(min_length=1)] | None = None
    """The basis functions kept, when not all."""
    coefficients_re: list[Coefficient]
    """Real parts of the shape's coefficients, one per basis function."""
    coefficients_im: list[Coefficient]
    """Imaginary parts of the shape's coefficients."""
    residual_std: float = Number(ge=0.0, le=1e3)
    """Standard deviation of the scan's residual about the shape."""
    coefficient_covariance: list[list[Annotated[float, Number(ge=-1e6, le=1e6)]]]
    """Covariance of the coefficients (each of the real and imaginary parts)."""
    orders: list[Annotated[int, Field(ge=0, le=10 * MAX_ORDER)]]
    """The orders tried."""
    score: list[Finite | None]
    """The criterion's score of each order tried."""


class Component(Shape):
    """One axis of a body's shape."""

    noun = "component"
    axis: Literal["x", "y", "z"]
    """The axis the component moves along."""


class BodyShape(Table):
    """A body's shape: one component per axis it moves along."""

    noun = "shape"
    components: Annotated[list[Component], Field(min_length=1, max_length=3)]
    """The components, each axis once."""


def _shape_kind(value: Any) -> str:
    return "body" if isinstance(value, dict) and "components" in value else "field"


AnyShape = Annotated[Annotated[Shape, Tag("field")] | Annotated[BodyShape, Tag("body")],
                     Discriminator(_shape_kind)]


class SpanEntry(Table):
    """The other scans' shapes of one harmonic, in a model of several scans."""

    noun = "span"
    harmonic: int
    """The harmonic (that of ``shapes[k]``)."""
    scans: list[int]
    """The scan of ``shapes[k]``, then of each shape of the span (indices into ``scans``)."""
    shapes: list[AnyShape]
    """The other scans' shapes."""
    couplings_re: Coupling
    """Real parts of each gauge's mass coupling with each shape of the span [kg m]."""
    couplings_im: Coupling
    """Imaginary parts of those couplings [kg m]."""


class SetAside(Table):
    """A scan record left out of the shapes."""

    noun = "set-aside record"
    record: int = Field(ge=1)
    """The record's number (from 1)."""
    reason: str
    """Why it was set aside."""


class ModelRig(Table):
    """What the model depends on in its rig."""

    noun = "rig"
    sha256: str = ""
    """SHA-256 of the keys."""
    keys: dict[str, Annotated[Any, AfterValidator(_rig_value)]] = Field(default_factory=dict)
    """Flat rig keys (``structure.length``, ``gauges[1].x``) to their number or name."""


class ModelFile(Table):
    """A spatial model file (MODEL.json)."""

    noun = "model"
    format: Literal["forcecal spatial model 1"]
    """What the file is."""
    source: str = ""
    """The scan (or scans) the model was built from."""
    f0_hz: float = Number(unit="Hz", gt=0.0, le=MAX_FREQUENCY_HZ)
    """The scan's drive frequency."""
    n_points: int = Field(0, ge=0, le=10**9)
    """Scan points."""
    gauges: Annotated[list[str], Field(min_length=1)]
    """The gauges' names."""
    harmonics: Annotated[list[Annotated[int, Field(ge=1, le=MAX_HARMONIC)]], Field(min_length=1)]
    """The harmonics the model holds, each once."""
    snr: list[NonNegative]
    """Signal-to-noise ratio of harmonics 1, 2, ..."""
    dropped: dict[str, str] = Field(default_factory=dict)
    """Harmonics left out, to the reason."""
    one_shape_serves_all: bool = False
    """Whether one shape serves every harmonic."""
    similarity_mac: list[list[Annotated[float, Number(ge=-1e-6, le=1 + 1e-6)]]]
    """Modal assurance criterion between the harmonics' shapes."""
    couplings_re: Coupling
    """Real parts of each harmonic's mass coupling with each gauge [kg m]."""
    couplings_im: Coupling
    """Imaginary parts of those couplings [kg m]."""
    shapes: list[AnyShape]
    """One shape per harmonic."""
    notes: list[str] = Field(default_factory=list)
    """What the build noted."""
    set_aside: list[SetAside] = Field(default_factory=list)
    """Scan records left out of the shapes."""
    rig: ModelRig = Field(default_factory=ModelRig)
    """The rig the model was built for."""
    scans: list[str] = Field(default_factory=list)
    """The scans of a model of several scans."""
    span: list[SpanEntry] = Field(default_factory=list)
    """Per harmonic, the other scans' shapes and couplings."""
    drive_re: list[Annotated[float, Number(unit="A", ge=-1e6, le=1e6)]] | None = None
    """Real parts of the scan's coil current, harmonics 0, 1, ..., aligned and scaled as the
    shapes are (its fundamental real) [A]; absent where the scan's records gave none."""
    drive_im: list[Annotated[float, Number(unit="A", ge=-1e6, le=1e6)]] | None = None
    """Imaginary parts of those harmonics [A]."""
    provenance: Provenance | None = None
    """Where the model comes from."""


def check_model_document(doc: Any, source: str) -> None:
    """Check a decoded spatial model file against its schema (see the module docstring).

    Parameters
    ----------
    doc : object
        What :func:`json.loads` gave.
    source : str
        The file, for the messages.

    Raises
    ------
    InputError
        Naming the file and the first key at fault.
    """
    label = f"model '{source}'"
    f = opened(doc, label, "format", MODEL_FORMAT,
               " (not a forcecal spatial model, or one of another version)")
    _check_model(f, validate(ModelFile, doc, label, InputError))


def _check_model(f: Faults, m: ModelFile) -> None:
    """What :class:`ModelFile` cannot say alone."""
    hs = m.harmonics
    if len(set(hs)) != len(hs):
        raise f.fail("harmonics", f"= {hs} names a harmonic twice")
    n_h, n_g = len(hs), len(m.gauges)
    if len(m.shapes) != n_h:
        raise f.fail("shapes", f"has {len(m.shapes)} shapes for {n_h} harmonics {hs}; expected "
                     "one shape per harmonic")
    for part in ("couplings_re", "couplings_im"):
        f.matrix(getattr(m, part), part, n_h, n_g)
    f.matrix(m.similarity_mac, "similarity_mac", n_h, n_h)
    if len(m.snr) < max(hs):
        raise f.fail("snr", f"has {len(m.snr)} values; expected one per harmonic 1..{max(hs)}")
    for h in m.dropped:
        if not h.strip().isdigit():
            raise f.fail(f"dropped.{h}", "must map a harmonic number to a reason")
    for k, s in enumerate(m.shapes):
        _check_shape(f, s, f"shapes[{k}]")
    if "span" in m.model_fields_set:
        _check_span(f, m, m.span)


def _check_span(f: Faults, m: ModelFile, span: list[SpanEntry]) -> None:
    """A multi-scan model's span: per harmonic the other scans' shapes and couplings."""
    if "scans" not in m.model_fields_set:
        raise f.fail("scans", "is missing; a model with a span names its scans")
    hs = m.harmonics
    if len(span) != len(hs):
        raise f.fail("span", f"has {len(span)} entries for {len(hs)} harmonics; expected one "
                     "per harmonic")
    for k, e in enumerate(span):
        key = f"span[{k}]"
        if e.harmonic != hs[k]:
            raise f.fail(f"{key}.harmonic", f"= {e.harmonic}; expected {hs[k]}, the harmonic of "
                         f"shapes[{k}]")
        if len(e.scans) != len(e.shapes) + 1:
            raise f.fail(f"{key}.scans", f"has {len(e.scans)} entries for {len(e.shapes) + 1} "
                         "shapes; expected the scan of shapes[k] then of each shape of the span")
        for j, i in enumerate(e.scans):
            f.whole(i, f"{key}.scans[{j}]", 0, len(m.scans) - 1)
        for j, s in enumerate(e.shapes):
            _check_shape(f, s, f"{key}.shapes[{j}]")
        for part in ("couplings_re", "couplings_im"):
            f.matrix(getattr(e, part), f"{key}.{part}", len(m.gauges), len(e.shapes))


def _check_shape(f: Faults, s: Shape | BodyShape, key: str) -> None:
    if isinstance(s, Shape):
        _check_field_shape(f, s, key)
        return
    axes: list[str] = []
    for j, c in enumerate(s.components):
        ck = f"{key}.components[{j}]"
        if c.axis in axes:
            raise f.fail(f"{ck}.axis", f"= {c.axis!r}; expected one of 'x', 'y', 'z', once")
        axes.append(c.axis)
        _check_field_shape(f, c, ck)


def _check_field_shape(f: Faults, s: Shape, key: str) -> None:
    """One shape's sizes against its basis, its covariance, and its uncertainty against its
    size."""
    for j, (lo, hi) in enumerate(s.domain):
        if not hi - lo >= 1e-6:
            raise f.fail(f"{key}.domain[{j}]", f"= [{lo}, {hi}] is empty or narrower than 1 um; "
                         "expected lo < hi (m)")
    basis_order = s.order
    if s.basis_order is not None:
        f.whole(s.basis_order, f"{key}.basis_order", s.order, MAX_ORDER)
        basis_order = s.basis_order
    n = available = n_functions(basis_order, len(s.domain))
    if s.columns is not None:
        for j, c in enumerate(s.columns):
            f.whole(c, f"{key}.columns[{j}]", 0, available - 1)
        n = len(s.columns)
    f.matrix(s.basis, f"{key}.basis", n, n)
    f.count(s.coefficients_re, f"{key}.coefficients_re", n)
    f.count(s.coefficients_im, f"{key}.coefficients_im", n)
    cov = s.coefficient_covariance
    f.matrix(cov, f"{key}.coefficient_covariance", n, n)
    f.covariance(cov, f"{key}.coefficient_covariance")
    scale = max(math.sqrt(sum(v * v for v in (*s.coefficients_re, *s.coefficients_im))),
                s.residual_std)
    for j, row in enumerate(cov):
        if math.sqrt(row[j]) > MAX_RELATIVE_STD * scale:
            raise f.fail(f"{key}.coefficient_covariance[{j}][{j}]",
                         f"= {row[j]!r}: a standard deviation "
                         f"{math.sqrt(row[j]) / max(scale, 1e-300):.3g} times the shape's own "
                         f"coefficients (at most {MAX_RELATIVE_STD:g}); a shape this uncertain "
                         "gives no force (is the file corrupt?)")
    if len(s.score) != len(s.orders):
        raise f.fail(f"{key}.score", f"has {len(s.score)} values for {len(s.orders)} orders")
