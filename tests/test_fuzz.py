"""Mutated inputs through every command: refused in one line, or accepted with sound outputs.

Hypothesis draws (input kind, seed) pairs, derandomized so every run tries the same cases;
:mod:`fuzz_inputs` turns each into one mutated file (or argument) and runs the command that
reads it in process. The contract (INTERFACES.md section 5): exit 0 with finite, valid and
physically bounded outputs, or exit 2 with one line naming the file and no output left; never
an internal error (exit 1, an exception) and never a silent wrong result. A key mutation (a key
misspelt, in the wrong case, moved, an unknown table, a key written twice: :mod:`fuzz_keys`)
is refused naming the file and the key, never run (issue 33). The long version is
``benchmarks/fuzz.py``.
"""

from __future__ import annotations

import pytest
from fuzz_inputs import (
    INTERNAL,
    KEY_KINDS,
    REFUSED,
    SILENT,
    UNCLEAN,
    VALUE_KINDS,
    Lab,
    build_lab,
    fuzz_one,
)
from fuzz_keys import FAMILIES
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

CASES = 150
"""Cases per run (about 12 per input kind of damaged values), about 8 s; the long campaign (200
per kind, the key kinds too) is ``benchmarks/fuzz.py``."""


@pytest.fixture(scope="module")
def lab(tmp_path_factory) -> Lab:
    return build_lab(tmp_path_factory.mktemp("fuzz") / "lab")


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    return tmp_path_factory.mktemp("fuzz-cases")


@settings(max_examples=CASES, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(kind=st.sampled_from(VALUE_KINDS), seed=st.integers(min_value=0, max_value=10**6))
def test_a_mutated_input_is_refused_cleanly_or_gives_sound_outputs(lab, work, kind, seed):
    outcome = fuzz_one(lab, work, kind, seed)
    assert outcome.outcome not in (INTERNAL, SILENT, UNCLEAN), (
        f"{outcome.outcome}: {kind} seed {seed} ({outcome.what}): {outcome.detail}")


@pytest.mark.parametrize("seed", range(len(FAMILIES)))
@pytest.mark.parametrize("kind", KEY_KINDS)
def test_a_mutated_key_is_refused_naming_the_file_and_the_key(lab, work, kind, seed):
    """Seeds 0-4 draw each family of key mutation once (misspelt, wrong case, moved, an
    unknown table, written twice) at any depth of the rig, the model or the calibration: the
    only right outcome is exit 2 with one line naming the file and the key's dotted path."""
    outcome = fuzz_one(lab, work, kind, seed)
    assert outcome.outcome == REFUSED, (
        f"{outcome.outcome}: {kind} seed {seed} ({outcome.what}): {outcome.detail}")


@pytest.mark.parametrize(("kind", "seed"), [("model", 118), ("rig", 172)])
def test_the_long_campaigns_finds_are_refused_in_one_line(lab, work, kind, seed):
    """Cases the long campaign (``benchmarks/fuzz.py``) found: a model whose shape coefficient
    has a variance of 1e6 (a standard deviation 1.7e8 times the shape's coefficients) had given
    forces with a stated uncertainty of 5e7 N at exit status 0; a rig whose drive lies above
    the run's Nyquist frequency was refused without naming the run or the rig's key."""
    outcome = fuzz_one(lab, work, kind, seed)
    assert outcome.outcome == REFUSED, (outcome.outcome, outcome.what, outcome.detail)
    assert "acquisition.frequency" in outcome.detail or "coefficient_covariance" in outcome.detail


@pytest.mark.parametrize("seed", [24, 55])
def test_an_absurd_frf_value_is_refused_naming_its_node(lab, work, seed):
    """Cases the long campaign found in a broadband scan exported as FRFs: one line's value
    set to 1e300 (seed 24) or 1e308 (seed 55) had overflowed the span's fit into numpy's
    warnings and an internal error; the FRF's magnitude is now refused as implausible, naming
    the node."""
    outcome = fuzz_one(lab, work, "scan_frf", seed)
    assert outcome.outcome == REFUSED, (outcome.outcome, outcome.what, outcome.detail)
    assert "FRF reaches" in outcome.detail and "not plausible" in outcome.detail
