"""Jobs carry their inputs, never a path: a campaign's calibration job holds its manifest's rows
and records read by the client, so the workers of a real cluster (a ``dask scheduler`` and two
``dask worker`` processes started in a folder without the files, the files then moved away)
compute the serial path's calibrations to the last digit; the rig and the model that every
job shares go to a cluster once, and the jobs are taken (their campaigns read) as the workers
need them."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import pytest

import forcecal
from forcecal.campaign import calibrate_campaign
from forcecal.campaign.runs import CampaignInputs
from forcecal.cli.main import main
from forcecal.cluster import pool
from forcecal.cluster.jobs import calibrate_jobs
from forcecal.cluster.pool import run_jobs
from forcecal.model.spatial import build_spatial_model

MANIFESTS = ("manifest_small.csv", "second.csv")


@pytest.fixture(scope="module")
def moved(campaign_dir, tmp_path_factory):
    """Two campaigns (the small one under two manifest names) copied into a folder, their
    jobs taken from the copy, the first one's serial result computed from its paths, then the
    folder renamed: (jobs, [serial result], an empty folder for the workers' working
    folder)."""
    base = tmp_path_factory.mktemp("remote")
    folder = base / "campaign"
    (folder / "runs").mkdir(parents=True)
    manifest = campaign_dir / MANIFESTS[0]
    for line in manifest.read_text(encoding="utf-8").splitlines()[1:]:
        shutil.copy(campaign_dir / line.split(",")[0], folder / "runs")
    for name in MANIFESTS:
        shutil.copy(manifest, folder / name)
    shutil.copy(campaign_dir / "rig.toml", folder)
    shutil.copy(campaign_dir / "scan.uff", folder)
    rig = forcecal.load_rig(folder / "rig.toml")
    model = build_spatial_model(rig, forcecal.read_scan(campaign_dir / "scan.uff", rig=rig))
    manifests = [str(folder / name) for name in MANIFESTS]
    jobs = list(calibrate_jobs(rig, model, manifests, False))   # each job taken: read
    serial = [calibrate_campaign(rig, model, manifests[0], workers=1)]
    folder.rename(base / "elsewhere")                  # no path of the jobs leads anywhere now
    (base / "empty").mkdir()
    return jobs, serial, base / "empty"


def test_a_job_holds_its_records_and_no_path(moved):
    jobs, _, _ = moved
    rig, model, campaign, ac_only, laws = jobs[0]
    assert isinstance(campaign, CampaignInputs) and ac_only is False and laws is None
    assert sorted(Path(p).name for p in campaign.records) == [
        "g0800_dc06_ac02.csv", "g1000_dc06_ac02.csv", "g1200_dc06_ac02.csv", "tare.csv"]
    assert jobs[1][0] is rig and jobs[1][1] is model          # shared, to be sent once
    assert not any(Path(p).exists() for p in campaign.records)


@pytest.fixture(scope="module")
def scheduler(moved, tmp_path_factory):
    """The address of a Dask cluster of separate processes, as a lab's cluster is: a ``dask
    scheduler`` and two ``dask worker`` processes on localhost, the workers started in the
    empty folder (they see none of the client's files)."""
    pytest.importorskip("distributed")
    info = tmp_path_factory.mktemp("dask") / "scheduler.json"
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    common = ["--no-dashboard"]
    started = [subprocess.Popen([sys.executable, "-m", "dask", "scheduler", "--host",
                                 "127.0.0.1", "--port", "0", "--scheduler-file", str(info),
                                 *common], cwd=moved[2], env=env,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        _wait_for(info.exists, "the scheduler's file")
        started += [subprocess.Popen([sys.executable, "-m", "dask", "worker", "--scheduler-file",
                                      str(info), "--nthreads", "1", "--nworkers", "1",
                                      "--no-nanny", *common], cwd=moved[2], env=env,
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                    for _ in range(2)]
        address = json.loads(info.read_text(encoding="utf-8"))["address"]
        with distributed_client(address) as client:
            client.wait_for_workers(2, timeout=60)
        yield address
    finally:
        for process in started:            # nothing of theirs to keep: no graceful close
            process.kill()
            process.wait(timeout=20)


def _wait_for(ready, what: str, seconds: float = 30.0) -> None:
    deadline = time.monotonic() + seconds
    while not ready():
        assert time.monotonic() < deadline, f"{what} did not appear in {seconds:g} s"
        time.sleep(0.1)


def distributed_client(address: str):
    from distributed import Client

    return Client(address, timeout=30)


def test_calibrate_on_a_remote_scheduler_writes_the_serial_paths_results(moved, scheduler,
                                                                          tmp_path, capsys):
    """``forcecal calibrate --scheduler tcp://...`` against the separate processes: each
    campaign's calibration.json, in a folder named after its manifest, holds the serial path's
    result."""
    folder = moved[2].parent / "elsewhere"
    assert main(["calibrate", str(folder / "rig.toml"), str(folder / "scan.uff"), "--no-report",
                 "--manifest", *(str(folder / m) for m in MANIFESTS), "-o", str(tmp_path),
                 "--scheduler", scheduler]) == 0
    out = capsys.readouterr().out
    assert [line for line in out.splitlines() if line.endswith("calibration.json")] == [
        str(tmp_path / Path(name).stem / "calibration.json") for name in MANIFESTS]
    serial = json.dumps(moved[1][0].to_json())           # its files read before the move
    for name in MANIFESTS:
        want = serial.replace(str(folder.with_name("campaign")), str(folder))
        want = want.replace(f"{folder}/{MANIFESTS[0]}", f"{folder}/{name}")
        assert json.loads((tmp_path / Path(name).stem / "calibration.json")
                          .read_text(encoding="utf-8")) == json.loads(want)


class _Taken(Sequence):
    """Jobs ``-k``, recording which are taken."""

    def __init__(self, n: int) -> None:
        self.n = n
        self.taken: list[int] = []

    def __len__(self) -> int:
        return self.n

    def __getitem__(self, k):
        self.taken.append(k)
        return -k


def test_jobs_are_taken_as_the_workers_need_them(scheduler):
    jobs, seen = _Taken(20), []
    out = run_jobs(abs, jobs, scheduler=scheduler,
                   progress=lambda done, total, name: seen.append((done, len(jobs.taken))))
    assert out == list(range(20)) and sorted(jobs.taken) == list(range(20))     # each once
    # two worker threads: four submitted and not done at most, and four more read ahead
    assert all(taken <= done + 8 for done, taken in seen)


class _Client:
    """A Dask client's ``scatter``, recorded."""

    def __init__(self) -> None:
        self.sent: list[list[object]] = []

    def scatter(self, items: list[object], hash: bool = True) -> list[str]:
        self.sent.append(items)
        return [f"future-{k}" for k in range(len(items))]


def test_inputs_that_jobs_share_are_sent_once():
    rig, model = {"rig": 1}, [0.0] * 3
    jobs = [(rig, model, {"runs": k}, False, 0) for k in range(3)]
    client = _Client()
    shared = pool._share(client, jobs[:2])
    assert client.sent == [[rig, model]]
    sent = [pool._with_shared(job, shared) for job in jobs]
    assert [job[:2] for job in sent] == [("future-0", "future-1")] * 3
    assert [job[2:] for job in sent] == [job[2:] for job in jobs]    # the rest within each job
    assert pool._share(client, ["a", "b"]) == {} and pool._share(client, jobs[:1]) == {}
    assert len(client.sent) == 1


def test_a_campaign_is_read_when_its_job_is_taken(campaign_dir, tmp_path):
    manifest = shutil.copy(campaign_dir / MANIFESTS[0], tmp_path / "m.csv")
    (tmp_path / "runs").symlink_to(campaign_dir / "runs")
    rig = forcecal.load_rig(campaign_dir / "rig.toml")
    jobs = calibrate_jobs(rig, None, [str(manifest)], False)
    assert len(jobs) == 1 and jobs[:0] == []
    Path(manifest).write_text("run\nnowhere.csv\n", encoding="utf-8")
    with pytest.raises(forcecal.errors.InputError, match=r"nowhere\.csv"):
        jobs[0]
    with pytest.raises(forcecal.errors.InputError, match=r"nowhere\.csv"):
        calibrate_jobs(rig, None, [str(manifest)], False)


def test_a_bad_manifest_among_several_is_refused_before_any_job(campaign_dir, tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("run\nnowhere.csv\n", encoding="utf-8")
    code = main(["calibrate", str(campaign_dir / "rig.toml"), str(campaign_dir / "scan.uff"),
                 "--manifest", str(campaign_dir / MANIFESTS[0]), str(bad), "-o",
                 str(tmp_path / "out"), "-q"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "nowhere.csv" in err[0]
    assert not (tmp_path / "out").exists()
