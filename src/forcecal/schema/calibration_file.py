"""The calibration file's schema (calibration.json, format "forcecal-calibration" version 1;
INTERFACES.md section 5): every key :meth:`forcecal.actuator.Calibration.to_json` writes (its
law over frequency, :meth:`forcecal.actuator.FrequencyLaw.to_json`, included) and every key a
campaign adds beside them (the chosen law, K_total, the reactions-only comparison, the
repeatability, the uncertainty budget, the campaign and its runs), every other key refused.

:func:`check_calibration_document` validates a decoded document against
:class:`CalibrationFile`, then checks what the declared keys cannot say alone: the law known,
its parameters named, each covariance of the law's size and a covariance, each range ordered.
Each fault is one line naming the file and the key (``uncertainty.type_b.covariance[1][0]``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Annotated, Any, Literal

from pydantic import ConfigDict, Field

from ..errors import InputError
from .json_files import Faults, Finite, NonNegative, Provenance, Table, opened, short
from .keys import Number, nearest_key, validate

__all__ = ["check_calibration_document"]

CALIBRATION_FORMAT = "forcecal-calibration"
"""The ``format`` a calibration file carries (with ``version`` 1)."""
CALIBRATION_VERSIONS = (1,)

Parameter = Annotated[float, Number(ge=-1e12, le=1e12)]
Covariance = list[list[Annotated[float, Number(ge=-1e24, le=1e24)]]]
Score = Finite | None
"""A number a campaign writes as null when it is not finite."""
Named = dict[str, NonNegative]
"""A standard uncertainty per parameter name."""
Currents = Annotated[list[Annotated[float, Number(ge=-1e5, le=1e5)]],
                     Field(min_length=2, max_length=2)]
"""[lo, hi] of the currents calibrated [A]."""
Gaps = Annotated[list[Annotated[float, Number(ge=0.0, le=0.1)]], Field(min_length=2, max_length=2)]
"""[lo, hi] of the gaps calibrated [m]."""
Fluxes = Annotated[list[Annotated[float, Number(ge=-10.0, le=10.0)]],
                   Field(min_length=2, max_length=2)]
"""[lo, hi] of the fluxes calibrated [Wb]."""
Frequencies = Annotated[list[Annotated[float, Number(ge=0.0, le=1e6)]],
                        Field(min_length=2, max_length=2)]
"""[lo, hi] of the frequencies calibrated [Hz]."""


class FrequencyParams(Table):
    """K, s_fe and tau of a law over frequency."""

    noun = "parameter"
    K: Parameter
    """The force constant [N m^2/A^2]."""
    s_fe: Parameter
    """The core's equivalent gap [m]."""
    tau: Parameter
    """The eddy currents' time constant [s]."""


class FrequencyStep(Table):
    """K(f) and the lag at one frequency step of a stepped-sine campaign."""

    noun = "step"
    frequency: Finite
    """The step's frequency [Hz]."""
    n_runs: int = Field(ge=0)
    """Runs at the step."""
    gain: Finite
    """K(f) / K."""
    gain_std: Finite
    """Its standard uncertainty."""
    k: Finite
    """K(f) [N m^2/A^2]."""
    k_std: Finite
    """Its standard uncertainty."""
    lag_deg: Finite
    """The force's lag behind i^2 [deg]."""
    lag_deg_std: Finite
    """Its standard uncertainty [deg]."""


FrequencyModelName = Literal["first-order", "half-order"]
"""The core's response over frequency (``forcecal.actuator.frequency_models``)."""


class FrequencyCandidate(Table):
    """One model of the core's response a calibration tried, with its scores (a skipped one:
    its name and reason)."""

    noun = "frequency-model candidate"
    model: FrequencyModelName
    """The model."""
    formula: str = ""
    """The law, as a formula."""
    params: FrequencyParams | None = None
    """Its fitted parameters."""
    stderr: FrequencyParams | None = None
    """Their standard uncertainties."""
    chi2: Score = None
    """The fit's chi-square."""
    dof: int = Field(0, ge=0, le=10**9)
    """Its degrees of freedom."""
    aic: Score = None
    """Akaike's information criterion."""
    bic: Score = None
    """The Bayesian information criterion."""
    held_out: Score = None
    """RMS relative error of the force's phasors of each frequency step left out in turn."""
    held_out_steps: list[Score] = Field(default_factory=list)
    """That error per step left out, by frequency."""
    skipped: str | None = None
    """Why the model could not be fitted."""


class FrequencySelection(Table):
    """The models of the core's response tried, and why one was chosen."""

    noun = "frequency-model selection"
    reason: str = ""
    """Why the chosen model was chosen."""
    candidates: list[FrequencyCandidate] = Field(default_factory=list)
    """Every model tried."""


class FrequencyLawKeys(Table):
    """The actuator's law over frequency (``frequency_law``)."""

    noun = "frequency-law"
    model: str = ""
    """The law, as a formula."""
    frequency_model: FrequencyModelName = "first-order"
    """The core's response; absent (a file written before the choice): first order."""
    selection: FrequencySelection | None = None
    """The models tried and why this one (absent when one was fitted)."""
    param_names: list[str] = Field(default_factory=list)
    """K, s_fe, tau."""
    param_units: list[str] = Field(default_factory=list)
    """Their units."""
    params: FrequencyParams
    """The parameters."""
    stderr: FrequencyParams | None = None
    """Their standard uncertainties."""
    covariance: Covariance
    """Their covariance (K, s_fe, tau)."""
    n_poles: int = Field(ge=1, le=1000)
    """Poles the total force sums over."""
    frequency_range: Frequencies
    """Frequencies calibrated [Hz]."""
    current_range: Currents
    """Currents calibrated [A]."""
    gap_range: Gaps
    """Gaps calibrated [m]."""
    chi2: float | None = Number(ge=0.0, le=1e30, default=None)
    """The fit's chi-square."""
    dof: int = Field(0, ge=0, le=10**9)
    """Its degrees of freedom."""
    covariance_scale: float = Number(ge=0.0, le=1e30, default=1.0)
    """The factor the covariance was scaled by."""
    steps: list[FrequencyStep] = Field(default_factory=list)
    """K(f) and the lag at every step."""


class Candidate(Table):
    """One law of the selection table (a skipped law: its name and reason)."""

    noun = "candidate"
    law: str
    """The law's name."""
    formula: str = ""
    """The law."""
    params: dict[str, Score] = Field(default_factory=dict)
    """Its fitted parameters."""
    stderr: dict[str, Score] = Field(default_factory=dict)
    """Their standard uncertainties (the residual's)."""
    stderr_statistical: dict[str, Score] = Field(default_factory=dict)
    """Their statistical standard uncertainties (propagated from the noise)."""
    aic: Score = None
    """Akaike's criterion."""
    bic: Score = None
    """Bayes' criterion."""
    held_out: Score = None
    """The held-out error."""
    rms_residual: Score = None
    """The fit's RMS residual."""
    skipped: str = ""
    """Why the law was skipped."""


class Part(Table):
    """The statistical part of the parameters' uncertainty."""

    noun = "uncertainty-part"
    stderr: Named
    """Standard uncertainty per parameter."""
    covariance: Covariance
    """Covariance of the parameters."""


class TypeBUsed(Table):
    """The rig's type-B standard uncertainties used."""

    noun = "type-B"
    gauge_scale: NonNegative
    """Gauge scale (relative)."""
    probe_scale: NonNegative
    """Probe scale (relative)."""
    current_scale: NonNegative
    """Current sensor scale (relative)."""
    position: NonNegative
    """Positions [m]."""
    mass: NonNegative
    """Masses (relative)."""
    gap: NonNegative
    """Static gaps [m]."""


class TypeBPart(Part):
    """The type-B part of the parameters' uncertainty."""

    declared: bool = False
    """Whether the rig file declares its type-B uncertainties."""
    standard_uncertainties: TypeBUsed | None = None
    """Those used."""


class BudgetRow(Table):
    """One source of the uncertainty budget: its kind, and its standard uncertainty of each
    parameter (keyed by the law's parameter names, checked against the law)."""

    model_config = ConfigDict(extra="allow")
    noun = "budget"
    kind: str = ""
    """Statistical or type B."""


class KTotalBudget(Table):
    """K_total's standard uncertainties (n_poles K)."""

    noun = "k_total"
    stderr: NonNegative
    """Combined."""
    expanded: NonNegative
    """Expanded (k u)."""
    statistical: NonNegative
    """Statistical."""
    type_b: NonNegative
    """Type B."""
    budget: Named = Field(default_factory=dict)
    """Per source."""


class Uncertainty(Table):
    """The parameters' uncertainty with its budget (a campaign's ``uncertainty``)."""

    noun = "uncertainty"
    method: str = ""
    """How it was obtained."""
    coverage_factor: float = Number(gt=0.0, le=10.0)
    """k of the expanded uncertainties."""
    param_names: list[str]
    """The law's parameters."""
    stderr: Named
    """Combined standard uncertainty per parameter."""
    expanded: Named
    """Expanded uncertainty per parameter."""
    correlation: list[list[Annotated[float, Number(ge=-1.0 - 1e-9, le=1.0 + 1e-9)]]]
    """Correlation of the combined covariance."""
    statistical: Part
    """The statistical part."""
    type_b: TypeBPart
    """The type-B part."""
    budget: dict[str, BudgetRow]
    """Every source's standard uncertainties."""
    residual_stderr: Named = Field(default_factory=dict)
    """The fit's residual standard uncertainties."""
    run_scatter_stderr: Named | None = None
    """The standard uncertainties clustered by run (null with fewer than two runs)."""
    n_runs: int = Field(0, ge=0)
    """Runs of the campaign."""
    k_total: KTotalBudget | None = None
    """K_total's, when the law has a K."""


class Chosen(Table):
    """The law a campaign chose, and why."""

    noun = "chosen"
    law: str
    """The law's name."""
    reason: str = ""
    """Why."""
    held_out_tolerance: Score = None
    """The held-out error's tolerance (relative)."""
    held_out_scheme: str = ""
    """How the held-out error was computed."""


class KTotal(Table):
    """K_total = n_poles K with its uncertainty, beside the ideal value."""

    noun = "k_total"
    value: Score = None
    """K_total [N m^2/A^2]."""
    stderr: Score = None
    """Its combined standard uncertainty."""
    stderr_statistical: Score = None
    """Its statistical standard uncertainty."""
    expanded: Score = None
    """Its expanded uncertainty."""
    coverage_factor: Score = None
    """k of the expanded uncertainty."""
    ideal: Score = None
    """The ideal value mu0 N^2 A / 4 from the rig."""
    ratio_to_ideal: Score = None
    """K_total / ideal."""
    n_poles: int = Field(1, ge=1, le=1000)
    """Poles."""
    note: str = ""
    """What the numbers are."""


class ReactionsOnly(Table):
    """The laws fitted to the reactions-only force (inertia ignored), for comparison."""

    noun = "reactions-only"
    error: str | None = None
    """Why there is no comparison."""
    chosen: str = ""
    """The law chosen for that force."""
    candidates: list[Candidate] = Field(default_factory=list)
    """The selection table of that force."""
    k_total: Score = None
    """Its K_total."""
    k_total_error: Score = None
    """Its K_total relative to the corrected force's."""
    s_fe: Score = None
    """Its s_fe [m]."""
    force_error_rms: Score = None
    """The RMS of its force relative to the corrected force's."""
    note: str = ""
    """What the numbers are."""


class RepeatGroup(Table):
    """One repeated setpoint of a campaign."""

    noun = "group"
    gap: Score = None
    """The setpoint's static gap [m]."""
    gaps: dict[str, Finite] = Field(default_factory=dict)
    """Its per-pole static gaps [m]."""
    labels: dict[str, str] = Field(default_factory=dict)
    """Its labels."""
    runs: list[str]
    """The runs repeating it."""
    k_total: list[Score] = Field(default_factory=list)
    """K_total refitted to each run."""
    amplitude: list[Score] = Field(default_factory=list)
    """Each run's force amplitude [N]."""
    amplitude_rel_std: Score = None
    """Their relative standard deviation."""
    k_total_rel_std: Score = None
    """K_total's relative standard deviation."""
    mean_force: list[Score] = Field(default_factory=list)
    """Each run's mean force [N]."""
    mean_force_rel_std: Score = None
    """Their relative standard deviation."""


class Repeatability(Table):
    """The spread over a campaign's repeated setpoints."""

    noun = "repeatability"
    k_total_rel_std: Score = None
    """Pooled relative standard deviation of K_total."""
    mean_force_rel_std: Score = None
    """Of the mean force."""
    amplitude_rel_std: Score = None
    """Of the force amplitude."""
    groups: list[RepeatGroup] = Field(default_factory=list)
    """One per repeated setpoint."""


class CampaignKeys(Table):
    """What a campaign was made of."""

    noun = "campaign"
    manifest: str
    """The campaign's manifest."""
    n_runs: int = Field(ge=0)
    """Its runs."""
    tares: list[str] = Field(default_factory=list)
    """Its tare records."""
    ac_only: bool = False
    """Whether the gauges are AC-coupled."""
    samples_per_period: int = Field(ge=0)
    """Samples per period of each run."""
    n_observations: int = Field(ge=0)
    """Samples the law was fitted to."""
    dc_deflection: str = ""
    """How the DC deflection was obtained."""


class RunSummary(Table):
    """One run of a campaign."""

    noun = "run"
    run: str
    """The run's name."""
    file: str
    """Its file."""
    group: int = Field(ge=0)
    """Its index."""
    static_gap: list[Score] = Field(default_factory=list)
    """Per-pole static gaps [m]."""
    labels: dict[str, str] = Field(default_factory=dict)
    """Its manifest labels."""
    tare: str | None = None
    """The tare record used."""
    f0_hz: Score = None
    """Its fundamental [Hz]."""
    mean_force: Score = None
    """Its mean force [N]."""
    fundamental_amplitude: Score = None
    """Its fundamental's amplitude [N]."""
    force_range: list[Score] = Field(default_factory=list)
    """Its force's [min, max] [N]."""
    inertia_share: Score = None
    """The inertia's share of its force."""
    current_range: list[Score] = Field(default_factory=list)
    """Its currents' [min, max] [A]."""
    gap_range: list[Score] = Field(default_factory=list)
    """Its gaps' [min, max] [m]."""
    dc_deflection: list[Score] = Field(default_factory=list)
    """The probes' DC deflection."""
    dc_misfit: Score = None
    """The quasi-static shape's misfit [m]."""
    residual_rms: Score = None
    """The law's RMS residual on it [N]."""
    notes: list[str] = Field(default_factory=list)
    """What its reconstruction noted."""


class CalibrationFile(Table):
    """A calibration file (calibration.json)."""

    noun = "calibration"
    format: Literal["forcecal-calibration"]
    """What the file is."""
    version: Literal[1]
    """The file's version."""
    law: str
    """The law's name (checked against the known laws)."""
    formula: str = ""
    """The law."""
    param_names: list[str] = Field(default_factory=list)
    """Its parameters."""
    param_units: list[str] = Field(default_factory=list)
    """Their units."""
    params: dict[str, Parameter]
    """The parameters, by name."""
    stderr: dict[str, Score] = Field(default_factory=dict)
    """Their standard uncertainties."""
    covariance: Covariance
    """Their covariance, in the law's order."""
    n_poles: int = Field(ge=1, le=1000)
    """Poles the total force sums over."""
    current_range: Currents
    """Currents calibrated [A]."""
    gap_range: Gaps
    """Gaps calibrated [m]."""
    flux_range: Fluxes | None = None
    """Fluxes calibrated [Wb], when measured."""
    candidates: list[Candidate] = Field(default_factory=list)
    """The selection table, one row per law."""
    frequency_law: FrequencyLawKeys | None = None
    """The law over frequency, from a stepped-sine campaign."""
    chosen: Chosen | None = None
    """The law a campaign chose, and why."""
    k_total: KTotal | None = None
    """K_total beside the ideal."""
    reactions_only: ReactionsOnly | None = None
    """The reactions-only comparison."""
    repeatability: Repeatability | None = None
    """The spread over repeated setpoints."""
    uncertainty: Uncertainty | None = None
    """The parameters' uncertainty with its budget."""
    campaign: CampaignKeys | None = None
    """What the campaign was made of."""
    runs: list[RunSummary] = Field(default_factory=list)
    """The campaign's runs."""
    provenance: Provenance | None = None
    """Where the calibration comes from."""


class _FrequencyLawOnly(Table):
    """A law over frequency alone, named as in a calibration file."""

    noun = "calibration"
    frequency_law: FrequencyLawKeys
    """The law."""


def check_calibration_document(doc: Any, source: str, get_law: Callable[[str], Any]) -> None:
    """Check a decoded calibration file against its schema (see the module docstring).

    Parameters
    ----------
    doc : object
        What :func:`json.loads` gave.
    source : str
        The file, for the messages.
    get_law : callable
        The law of a name (:func:`forcecal.actuator.laws.get_law`), to check the parameters'
        names and count.

    Raises
    ------
    InputError
        Naming the file and the first key at fault.
    """
    label = f"calibration '{source}'"
    f = opened(doc, label, "format", CALIBRATION_FORMAT)
    version = doc.get("version", CALIBRATION_VERSIONS[0])
    if isinstance(version, bool) or version not in CALIBRATION_VERSIONS:
        raise f.fail("version", f"= {short(version)}; this forcecal reads version "
                     f"{', '.join(map(str, CALIBRATION_VERSIONS))}")
    _parameter_tables(f, doc, "", _law_names(doc, get_law, ()), get_law)
    cal = validate(CalibrationFile, doc, label, InputError)
    try:
        law = get_law(cal.law)
    except (KeyError, ValueError, InputError):
        raise f.fail("law", f"= {cal.law!r} is not a known law") from None
    _check_values(f, cal, law)
    if cal.frequency_law is not None:
        _check_frequency_law(f, cal.frequency_law, "frequency_law")
    if cal.uncertainty is not None:
        _check_budget(f, cal.uncertainty, law)


PARAMETER_TABLES = ("params", "stderr", "stderr_statistical", "expanded", "residual_stderr",
                    "run_scatter_stderr")
"""The tables keyed by a law's parameters, wherever they sit (the file's law, a candidate's)."""


def _law_names(table: dict, get_law: Callable[[str], Any],
               outer: tuple[str, ...]) -> tuple[str, ...]:
    """The parameter names of the law a table names (``law``), else those of the table that
    holds it."""
    try:
        return tuple(get_law(table["law"]).param_names)
    except (KeyError, ValueError, TypeError, InputError):
        return outer


def _parameter_tables(f: Faults, obj: Any, path: str, names: tuple[str, ...],
                      get_law: Callable[[str], Any]) -> None:
    """Every table keyed by a law's parameters holds only those names: checked before the
    schema, so that a key moved or misspelt there is named, not the key it left missing."""
    if isinstance(obj, list):
        for k, item in enumerate(obj):
            _parameter_tables(f, item, f"{path}[{k}]", names, get_law)
        return
    if not isinstance(obj, dict) or path.startswith("frequency_law"):
        return
    names = _law_names(obj, get_law, names)
    for key, value in obj.items():
        where = f"{path}.{key}" if path else str(key)
        for n in (value if key in PARAMETER_TABLES and isinstance(value, dict) and names
                  else ()):
            if n not in names:
                near = nearest_key(str(n), list(names))
                raise f.fail(f"{where}.{n}", "is not a parameter of the law" + (
                    f"; did you mean '{near}'?" if near else f" ({', '.join(names)})"))
        _parameter_tables(f, value, where, names, get_law)


def check_frequency_law(obj: Any, source: str) -> FrequencyLawKeys:
    """A calibration file's ``frequency_law`` checked against its schema.

    Parameters
    ----------
    obj : object
        The decoded block.
    source : str
        The calibration file, for the messages.

    Returns
    -------
    FrequencyLawKeys
        The validated block.

    Raises
    ------
    InputError
        Naming the file and the first key at fault (``frequency_law.params.tau``).
    """
    label = f"calibration '{source}'"
    law = validate(_FrequencyLawOnly, {"frequency_law": obj}, label, InputError).frequency_law
    _check_frequency_law(Faults(label), law, "frequency_law")
    return law


def _check_values(f: Faults, cal: CalibrationFile, law: Any) -> None:
    """A calibration's parameters for ``law`` (a :class:`~forcecal.actuator.laws.Law`), their
    covariance and the calibrated ranges."""
    whose = f"law {law.name!r}"
    f.names(cal.params, "params", law.param_names, whose)
    p = law.n_params
    f.matrix(cal.covariance, "covariance", p, p)
    f.covariance(cal.covariance, "covariance")
    f.ordered(cal.current_range, "current_range")
    f.ordered(cal.gap_range, "gap_range")
    if cal.flux_range is not None:
        f.ordered(cal.flux_range, "flux_range")


def _check_frequency_law(f: Faults, fl: FrequencyLawKeys, key: str) -> None:
    """A law over frequency's covariance and ranges."""
    f.matrix(fl.covariance, f"{key}.covariance", 3, 3)
    f.covariance(fl.covariance, f"{key}.covariance")
    for name in ("frequency_range", "current_range", "gap_range"):
        f.ordered(getattr(fl, name), f"{key}.{name}")


def _check_budget(f: Faults, unc: Uncertainty, law: Any) -> None:
    """The ``uncertainty`` block of a calibration for ``law``: the parameters' uncertainty
    budget a campaign's calibration carries."""
    names, p, whose = list(law.param_names), law.n_params, f"law {law.name!r}"
    if unc.param_names != names:
        raise f.fail("uncertainty.param_names", f"= {unc.param_names!r}; expected {names!r} for "
                     f"{whose}")
    for key in ("stderr", "expanded", "residual_stderr", "run_scatter_stderr"):
        values = getattr(unc, key)
        if values is not None and (values or key in ("stderr", "expanded")):
            f.names(values, f"uncertainty.{key}", names, whose)
    f.matrix(unc.correlation, "uncertainty.correlation", p, p)
    for part in ("statistical", "type_b"):
        block: Part = getattr(unc, part)
        f.names(block.stderr, f"uncertainty.{part}.stderr", names, whose)
        f.matrix(block.covariance, f"uncertainty.{part}.covariance", p, p)
        f.covariance(block.covariance, f"uncertainty.{part}.covariance")
    for source, row in unc.budget.items():
        key = f"uncertainty.budget.{source}"
        extra = row.model_extra or {}
        f.names(extra, key, names, whose)
        for n, v in extra.items():
            if isinstance(v, bool) or not isinstance(v, int | float) or not 0 <= v <= 1e30:
                raise f.fail(f"{key}.{n}", f"must be a number from 0 to 1e30, found {short(v)}")

