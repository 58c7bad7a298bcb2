"""Benchmark: many calibrations spread over a local Dask cluster of 1, 2 and 4 workers.

A production batch is many actuators, each with its own campaign. Here every job is one
campaign of the `campaign` preset's rig (a tare and eight runs of 0.5 s; noise redrawn per
job), calibrated as ``forcecal calibrate RIG MODEL --manifest M1 M2 ... --workers W`` does
(:func:`forcecal.cluster.run_jobs` with the CLI's own jobs, each campaign's manifest and records
read by the client and carried in its job, the reading timed with the jobs). Reported for each W:
the wall time (cluster start included; one worker too, a cluster of one), the cluster's start
alone, the speed-up over the serial path and the parallel efficiency (speed-up / W), the
efficiency once the cluster is up (the jobs' wall time alone: a running or remote cluster, or a
batch long enough that the start does not count), and the
overhead per job (the worker time a job costs beyond its serial compute:
``(W wall - serial) / jobs``) with its breakdown (:func:`breakdown`: start, slower compute,
transfer, deserialisation, idle workers, the client's reading). The results are checked
identical to the serial ones.

From the measured figures: what a 10,000-actuator batch would cost on a cluster of C cores,
``10000 * (serial_per_job + overhead_per_job) / C + start`` (the overhead the least measured).

Run:  .venv/bin/python benchmarks/cluster.py [--jobs 8] [--workers 1 2 4]
Writes benchmarks/results/cluster.json.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import pickle
import platform
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from forcecal.cluster.jobs import calibrate_job as _calibrate_job
from forcecal.cluster.jobs import calibrate_jobs as _calibrate_jobs
from forcecal.cluster.pool import _client, run_jobs
from forcecal.cluster.threads import limited
from forcecal.io.manifest import write_manifest
from forcecal.io.run_files import write_run_csv
from forcecal.model.spatial import build_spatial_model
from forcecal.simulate.magnet import Drive
from forcecal.simulate.presets import RunSpec, get_preset
from forcecal.simulate.virtual_rig import (
    build_model,
    measure_run,
    public_rig,
    record_scan,
    simulate_response,
)

RESULTS = Path(__file__).resolve().parent / "results" / "cluster.json"
BATCH = 10_000
"""Actuators of the batch whose cost is extrapolated."""


def campaigns(folder: Path, n_jobs: int):
    """``n_jobs`` campaigns of one rig (physics simulated once, noise redrawn per campaign):
    the rig, the model and the manifests."""
    base = get_preset("campaign")
    f = base.runs[0].drives[0].frequency
    specs = [RunSpec("tare", drives=(Drive("current", 0.0, 0.0, f),), gap=1.0e-3, duration=0.5,
                     tare=True)]
    specs += [RunSpec(f"g{g * 1e6:04.0f}_dc{dc * 10:02.0f}", drives=(Drive("current", dc, 0.2, f),),
                      gap=g, duration=0.5) for g in (0.8e-3, 1.0e-3, 1.2e-3) for dc in (0.4, 0.8)]
    specs += [RunSpec("g1000_dc06", drives=(Drive("current", 0.6, 0.2, f),), gap=1.0e-3,
                      duration=0.5)]
    preset = dataclasses.replace(base, runs=tuple(specs))
    beam = build_model(preset)
    rig = public_rig(preset)
    model = build_spatial_model(rig, record_scan(preset, np.random.default_rng(0), beam))
    responses = {s.name: simulate_response(preset, s.drives, s.gap, s.duration, beam)
                 for s in specs}
    manifests = []
    for j in range(n_jobs):
        rng = np.random.default_rng(100 + j)
        rows = []
        for s in specs:
            run = measure_run(preset, s, beam, responses[s.name], rng)
            write_run_csv(run, folder / f"unit{j:02d}" / f"{s.name}.csv")
            rows.append({"run": f"{s.name}.csv", "gap": s.gap, "tare": s.tare})
        manifests.append(str(write_manifest(folder / f"unit{j:02d}" / "manifest.csv", rows)))
    return rig, model, manifests


class _Timed(Sequence):
    """The jobs, the client's time spent taking each (reading its campaign) added up."""

    def __init__(self, jobs) -> None:
        self.jobs, self.seconds, self.bytes = jobs, 0.0, 0

    def __len__(self) -> int:
        return len(self.jobs)

    def __getitem__(self, k):
        t0 = time.perf_counter()
        job = self.jobs[k]
        self.seconds += time.perf_counter() - t0
        self.bytes += len(pickle.dumps(job[2]))          # the campaign's records, sent per job
        return job


def spread_over(rig, model, manifests: list[str], workers: int) -> tuple[list, dict]:
    """The campaigns calibrated over a local cluster of ``workers`` processes, started for the
    call as the command starts it (one worker too: the cluster's own cost, with no
    parallelism), and where the time went: the cluster's start (worker processes, their
    imports), the client's reading of the campaigns, and from the scheduler's task stream each
    job's compute, its inputs' transfer and deserialisation on the workers."""
    from distributed import get_task_stream

    t0 = time.perf_counter()
    with _client(workers, None) as client:
        start = time.perf_counter() - t0
        jobs = _Timed(_calibrate_jobs(rig, model, manifests, False))
        t0 = time.perf_counter()
        with get_task_stream(client) as stream:
            out = run_jobs(_calibrate_job, jobs, scheduler=client.scheduler.address)
        wall = time.perf_counter() - t0
    spent = {"compute": 0.0, "transfer": 0.0, "deserialize": 0.0}
    for task in stream.data:
        for part in task["startstops"]:
            if part["action"] in spent:
                spent[part["action"]] += part["stop"] - part["start"]
    return out, {"seconds_start": start, "seconds_wall": start + wall, "seconds_jobs": wall,
                 "client_reading_s": jobs.seconds, "records_bytes_per_job": jobs.bytes / len(jobs),
                 **{f"worker_{k}_s": v for k, v in spent.items()}}


def breakdown(row: dict, serial_per_job: float, n_jobs: int) -> dict:
    """Where each job's overhead went, in seconds per job: the cluster's start shared by the
    jobs, the compute slower than the serial path's (the workers share the cores and memory with
    each other and with the client), the inputs' transfer and deserialisation, the client's
    reading of the campaigns, and the workers' idle time (waiting for a job: scheduling, the
    client's submitting, the last jobs' tail)."""
    w = row["workers"]
    busy = row["worker_compute_s"] + row["worker_transfer_s"] + row["worker_deserialize_s"]
    return {"start": row["seconds_start"] * w / n_jobs,
            "slower_compute": row["worker_compute_s"] / n_jobs - serial_per_job,
            "transfer": row["worker_transfer_s"] / n_jobs,
            "deserialize": row["worker_deserialize_s"] / n_jobs,
            "idle": (w * row["seconds_jobs"] - busy) / n_jobs,
            "client_reading": row["client_reading_s"] / n_jobs}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=8, help="campaigns (default 8)")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2, 4])
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="forcecal-cluster-") as tmp:
        print(f"simulating {args.jobs} campaigns", flush=True)
        rig, model, manifests = campaigns(Path(tmp), args.jobs)
        print("serial", flush=True)
        t0 = time.perf_counter()
        with limited():                      # as the command runs it: one BLAS thread
            serial = run_jobs(_calibrate_job, _calibrate_jobs(rig, model, manifests, False),
                              workers=1)
        t_serial = time.perf_counter() - t0
        reference = [r.calibration.params.tolist() for r in serial]
        rows = []
        for w in args.workers:
            print(f"local cluster of {w} workers", flush=True)
            out, row = spread_over(rig, model, manifests, w)
            row = {"workers": w, **row, "speed_up": t_serial / row["seconds_wall"],
                   "identical": [r.calibration.params.tolist() for r in out] == reference,
                   "efficiency": t_serial / row["seconds_wall"] / w,
                   "efficiency_once_up": t_serial / row["seconds_jobs"] / w,
                   "overhead_per_job_s": (w * row["seconds_wall"] - t_serial) / args.jobs}
            row["overhead_breakdown_s_per_job"] = breakdown(row, t_serial / args.jobs, args.jobs)
            rows.append(row)
    per_job = t_serial / args.jobs
    spread = [r for r in rows if r["workers"] > 1] or rows
    best = min(spread, key=lambda r: r["overhead_per_job_s"])
    cost = per_job + max(best["overhead_per_job_s"], 0.0)   # worker time per job on a cluster
    batch = {f"{c}_cores_hours": (BATCH * cost / c + best["seconds_start"]) / 3600
             for c in (2, 64, 512)}
    res = {"machine": {"python": platform.python_version(), "cores": os.cpu_count(),
                       "processor": platform.processor() or platform.machine(),
                       "load_average": os.getloadavg()},
           "jobs": args.jobs, "runs_per_job": 8, "serial_seconds": t_serial,
           "serial_seconds_per_job": per_job, "by_workers": rows,
           "worker_seconds_per_job": cost, "batch_10000": batch}
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(res, indent=2) + "\n")
    print(f"\n{args.jobs} campaigns of 8 runs (+ tare), {os.cpu_count()} cores; serial "
          f"{t_serial:.1f} s ({per_job:.2f} s per campaign)")
    print(f"{'workers':>8}{'wall s':>9}{'start s':>9}{'speed-up':>10}{'efficiency':>11}"
          f"{'once up':>9}{'overhead/job s':>16}{'identical':>11}")
    for r in rows:
        print(f"{r['workers']:>8}{r['seconds_wall']:9.2f}{r['seconds_start']:9.2f}"
              f"{r['speed_up']:10.2f}{r['efficiency']:11.2f}{r['efficiency_once_up']:9.2f}"
              f"{r['overhead_per_job_s']:16.3f}{r['identical']!s:>11}")
    parts = list(rows[0]["overhead_breakdown_s_per_job"])
    print(f"\noverhead per job, s (of {per_job:.2f} s of serial compute):")
    print(f"{'workers':>8}" + "".join(f"{k:>16}" for k in parts))
    for r in rows:
        print(f"{r['workers']:>8}" + "".join(
            f"{r['overhead_breakdown_s_per_job'][k]:16.3f}" for k in parts))
    print(f"records sent per job: {rows[0]['records_bytes_per_job'] / 1e6:.2f} MB")
    print(f"10,000 actuators at {per_job:.2f} s of compute and {cost - per_job:.2f} s of overhead "
          "each (the least of the measured): "
          + ", ".join(f"{k.split('_')[0]} cores {v:.2f} h" for k, v in batch.items()))
    print(f"\nwritten: {RESULTS}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
