"""forcecal sets its own threads: inside a command and inside an API call the BLAS pools run on
one thread by default, on N with ``--threads N``, ``FORCECAL_THREADS=N`` or
``forcecal.threads(N)``, and are restored after; a bad value is refused in one line (exit 2
on the command line); jobs carry the limit to the workers."""

from __future__ import annotations

import os
import pickle
import sys

import numba
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

import forcecal
import forcecal.cli.main
from forcecal import api
from forcecal.cluster.pool import pool_map
from forcecal.cluster.threads import ENVIRONMENT, THREAD_VARIABLES, LimitedJob, limited

cli = sys.modules["forcecal.cli.main"]          # forcecal.cli.main is also the function's name
PREDICT = ["predict", "calibration.json", "--current", "1", "--gap", "0.001"]
"""A command's arguments (nothing is read: its handler is the spy)."""
OUTSIDE = 3
"""The BLAS threads around the calls: neither the default nor what the tests ask for."""


def blas_threads() -> set[int]:
    """The thread counts of every BLAS library loaded (NumPy's and SciPy's)."""
    return {pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"}


@pytest.fixture
def seen(monkeypatch):
    """The BLAS threads and OPENBLAS_NUM_THREADS inside each call of the spied command and API
    steps, under a BLAS limit of OUTSIDE and none of the variables set; checks that the limit
    is back after the test."""
    monkeypatch.delenv(ENVIRONMENT, raising=False)
    for name in THREAD_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    calls: list[tuple[set[int], str | None]] = []

    def spy(*_args, **_kwargs) -> int:
        calls.append((blas_threads(), os.environ.get("OPENBLAS_NUM_THREADS")))
        return 0

    class Drive:
        build_model = staticmethod(spy)

    monkeypatch.setitem(cli.COMMANDS, "predict", spy)
    monkeypatch.setattr(api, "drive_of", lambda _rig: Drive())
    monkeypatch.setattr(api, "calibrate_campaign", spy)
    with threadpool_limits(OUTSIDE, user_api="blas"):
        yield calls
        assert blas_threads() == {OUTSIDE}
        assert "OPENBLAS_NUM_THREADS" not in os.environ


def test_a_command_runs_on_one_thread_unless_told(seen, monkeypatch):
    assert cli.main(PREDICT) == 0
    assert blas_threads() == {OUTSIDE}                       # restored after the command
    assert cli.main([*PREDICT, "--threads", "2"]) == 0
    monkeypatch.setenv(ENVIRONMENT, "4")
    assert cli.main(PREDICT) == 0
    assert cli.main([*PREDICT, "--threads", "2"]) == 0       # the option before the variable
    assert seen == [({1}, "1"), ({2}, "2"), ({4}, "4"), ({2}, "2")]


def test_an_api_call_runs_on_one_thread_unless_told(seen, monkeypatch):
    forcecal.build_spatial_model(None, None)
    assert blas_threads() == {OUTSIDE}                       # restored after the call
    with forcecal.threads(2):
        forcecal.calibrate(None, None, "manifest.csv")       # its model, then its campaign:
    monkeypatch.setenv(ENVIRONMENT, "4")                     # an enclosing limit is kept
    forcecal.build_spatial_model(None, None)
    with forcecal.threads(2):
        forcecal.build_spatial_model(None, None)             # the call's limit first
    assert seen == [({1}, "1"), ({2}, "2"), ({2}, "2"), ({4}, "4"), ({2}, "2")]


@pytest.mark.parametrize("bad", ["0", "-1", "1.5", "two"])
def test_a_bad_thread_count_is_one_line_and_exit_2(bad, monkeypatch, capsys):
    monkeypatch.delenv(ENVIRONMENT, raising=False)
    assert cli.main([*PREDICT, "--threads", bad]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1
    assert f"argument --threads: '{bad}' is not a number of threads" in err
    monkeypatch.setenv(ENVIRONMENT, bad)
    assert cli.main(PREDICT) == 2
    err = capsys.readouterr().err
    assert err == f"forcecal: {ENVIRONMENT}: '{bad}' is not a number of threads; give a " \
                  "whole number >= 1\n"
    with pytest.raises(forcecal.InputError, match="not a number of threads"):
        forcecal.build_spatial_model(None, None)


@pytest.mark.parametrize("bad", [0, -2, 1.5, True, "x"])
def test_the_api_refuses_a_bad_thread_count(bad):
    with pytest.raises(forcecal.InputError, match=r"^forcecal\.threads: .* is not a number"):
        forcecal.threads(bad)


def test_jobs_carry_the_limit_to_their_workers(monkeypatch):
    monkeypatch.delenv(ENVIRONMENT, raising=False)
    job = pickle.loads(pickle.dumps(LimitedJob(os.getenv, 3)))    # as a worker receives it
    assert job("OPENBLAS_NUM_THREADS") == "3"
    with forcecal.threads(2):                                     # a spawned worker, told 2
        assert list(pool_map(os.getenv, ["OMP_NUM_THREADS"], workers=1)) == ["2"]
    assert list(pool_map(os.getenv, ["MKL_NUM_THREADS"], workers=1)) == ["1"]


def test_numbas_threads_are_limited_when_its_threading_layer_runs():
    launched = numba.config.NUMBA_NUM_THREADS
    numba.set_num_threads(launched)                  # starts the layer (forcecal's kernels don't)
    with limited(1):
        assert numba.get_num_threads() == 1
    assert numba.get_num_threads() == launched
