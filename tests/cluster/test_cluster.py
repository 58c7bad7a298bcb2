"""Many jobs over Dask: a local cluster of two workers gives the serial path's results, in
order, with progress as jobs complete, one BLAS thread per worker, and no worker left after
the command; the CLI spreads runs over it with outputs identical to the serial ones. The
module's tests start and close local clusters one after another (a batch script calling
forcecal in a loop): each finishes, none hangs, none leaves a process. A worker that dies, or a
cluster without workers, is one clear error, never a wait without end."""

from __future__ import annotations

import json
import multiprocessing
import os
import shutil
from pathlib import Path

import dask
import pytest
import tomli_w

from forcecal.cli.main import main
from forcecal.cluster import pool as cluster
from forcecal.cluster.pool import run_jobs
from forcecal.errors import ForcecalError, InputError
from forcecal.io.manifest import write_manifest
from forcecal.simulate.export import rig_to_dict


def _same_outputs(a: Path, b: Path, renamed: tuple[str, str] = ("", "")) -> None:
    """Every file of ``a`` is in ``b`` with the same content (JSON: but for the provenance and
    for ``b``'s file names ``renamed[1]`` standing for ``renamed[0]``)."""
    names = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file())
    assert names == sorted(p.relative_to(b) for p in b.rglob("*") if p.is_file())
    for name in names:
        if name.suffix == ".json":
            x = json.loads((a / name).read_text())
            y = json.loads((b / name).read_text().replace(renamed[1] or "\0", renamed[0]))
            x.pop("provenance", None)
            y.pop("provenance", None)
            assert x == y, name
        elif name.suffix in (".csv", ".h5"):
            assert (a / name).read_bytes() == (b / name).read_bytes(), name


def test_a_local_cluster_runs_the_jobs_in_order_and_leaves_nothing(monkeypatch):
    for name in cluster.THREAD_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    calls = []
    jobs = ["OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "FORCECAL_NOT_SET",
            "MALLOC_TRIM_THRESHOLD_", "MALLOC_MMAP_THRESHOLD_"]
    out = run_jobs(os.getenv, jobs, names=list("abcdef"), workers=2,
                   progress=lambda *args: calls.append(args))
    # in the jobs' order; glibc's allocator keeps its heap between a worker's arrays and jobs
    # (not Dask's 64 kB trim threshold, which made a first job fault in 1.8 GB of pages)
    assert out == ["1", "1", "1", None, str(256 << 20), str(32 << 20)]
    assert sorted(c[0] for c in calls) == [1, 2, 3, 4, 5, 6] and {c[1] for c in calls} == {6}
    assert sorted(c[2] for c in calls) == list("abcdef")
    assert "OPENBLAS_NUM_THREADS" not in os.environ          # the parent's left as it was
    assert multiprocessing.active_children() == []          # no worker outlives the call


def test_a_failing_job_raises_as_it_did_and_closes_the_cluster():
    with pytest.raises(ValueError, match="invalid literal"):
        run_jobs(int, ["1", "2", "x"], workers=2)
    assert multiprocessing.active_children() == []


def test_a_worker_that_dies_is_one_clear_error_naming_the_job():
    """A job that kills its worker process (out of memory, say) is given up with one line
    naming it, not retried without end."""
    pytest.importorskip("distributed")    # its defaults loaded before one is set for the test
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}), \
            pytest.raises(ForcecalError, match=r"job 'dies': the worker process running it died"):
        run_jobs(os._exit, [3, 3], names=["dies", "dies"], workers=2)
    assert multiprocessing.active_children() == []


def test_a_cluster_without_workers_gives_the_jobs_up_with_a_clear_error(monkeypatch):
    distributed = pytest.importorskip("distributed")
    monkeypatch.setattr(cluster, "WORKERLESS_S", 0.5)
    said = r"has had no worker for 0\.5 s with 2 jobs not done"
    with distributed.LocalCluster(n_workers=0, processes=False, dashboard_address=":0") as empty, \
            pytest.raises(ForcecalError, match=said):
        run_jobs(abs, [-1, -2], scheduler=empty.scheduler_address)


def test_one_worker_or_one_job_runs_serially_in_process():
    assert run_jobs(os.getpid, [None][:0], workers=2) == []
    assert run_jobs(abs, [-1, -2], workers=1) == [1, 2]


def test_an_unreachable_scheduler_is_one_clear_error(monkeypatch):
    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT_S", 1.0)
    with pytest.raises(InputError, match=r"--scheduler tcp://127\.0\.0\.1:9: no Dask scheduler"):
        run_jobs(abs, [-1, -2], scheduler="tcp://127.0.0.1:9")


def test_reconstruct_spreads_runs_over_two_workers_with_the_serial_outputs(paper_dir, tmp_path):
    rig, scan = str(paper_dir / "rig.toml"), str(paper_dir / "scan.uff")
    runs = []
    for k in range(2):                                       # two runs of distinct names
        runs.append(tmp_path / f"run{k}.csv")
        shutil.copy(paper_dir / "runs" / "paper.csv", runs[-1])
    args = ["reconstruct", rig, scan, *map(str, runs)]
    assert main([*args, "-o", str(tmp_path / "serial"), "--workers", "1", "-q"]) == 0
    assert main([*args, "-o", str(tmp_path / "dask"), "--workers", "2", "-q"]) == 0
    _same_outputs(tmp_path / "serial", tmp_path / "dask")


def test_two_manifests_of_one_name_are_refused(campaign_files, tmp_path, capsys):
    rig, model, manifest = campaign_files
    (tmp_path / "elsewhere").mkdir()
    twin = shutil.copy(manifest, tmp_path / "elsewhere" / manifest.name)
    assert main(["calibrate", rig, model, "--manifest", str(manifest), str(twin), "-o",
                 str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "rename one of them" in err[0]
    assert not (tmp_path / "out").exists()


@pytest.fixture(scope="module")
def campaign_files(tmp_path_factory) -> tuple[str, str, Path]:
    """A four-run campaign of the 'campaign' preset's rig (0.3 s records) in the public
    formats: (rig.toml, model.json, manifest.csv)."""
    import dataclasses

    import numpy as np

    from forcecal.io.run_files import write_run_csv
    from forcecal.model.spatial import build_spatial_model
    from forcecal.simulate.presets import Drive, RunSpec, get_preset
    from forcecal.simulate.virtual_rig import build_model, public_rig, record_run, record_scan

    folder = tmp_path_factory.mktemp("campaign-files")
    base = get_preset("campaign")
    f = base.runs[0].drives[0].frequency
    specs = [RunSpec("tare", drives=(Drive("current", 0.0, 0.0, f),), gap=1.0e-3, duration=0.3,
                     tare=True)]
    specs += [RunSpec(f"g{g * 1e6:04.0f}_dc{dc * 10:02.0f}", drives=(Drive("current", dc, 0.2, f),),
                      gap=g, duration=0.3) for g in (0.8e-3, 1.2e-3) for dc in (0.4, 0.8)]
    preset = dataclasses.replace(base, runs=tuple(specs),
                                 scan=dataclasses.replace(base.scan, n_points=31, record=0.3))
    rng = np.random.default_rng(7)
    beam = build_model(preset)
    rig = public_rig(preset)
    (folder / "rig.toml").write_text(tomli_w.dumps(rig_to_dict(rig)))
    build_spatial_model(rig, record_scan(preset, rng, beam)).save(folder / "model.json")
    rows = []
    for spec in specs:
        run, _ = record_run(preset, spec, rng, beam)
        write_run_csv(run, folder / "runs" / f"{spec.name}.csv")
        rows.append({"run": f"runs/{spec.name}.csv", "gap": spec.gap, "tare": spec.tare})
    manifest = write_manifest(folder / "manifest.csv", rows)
    return str(folder / "rig.toml"), str(folder / "model.json"), Path(manifest)
