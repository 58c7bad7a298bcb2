"""``forcecal demo``: the whole method on the built-in virtual rig.

Simulates the ``paper`` and ``campaign`` presets, builds the spatial model, reconstructs the
paper run, calibrates the campaign and writes the report.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

__all__: list[str] = []


def run_demo(out: Path, progress: Callable[[str], None] = lambda _m: None) -> Path:
    """Run every stage of the method on the virtual rig.

    Parameters
    ----------
    out : Path
        The output folder: the simulated files, the paper run's report and the campaign's
        calibration and report.
    progress : callable
        Called with a one-line message before each stage and each of its steps (every run
        simulated, every run of the campaign reconstructed).

    Returns
    -------
    Path
        The HTML report of the paper run.
    """
    from ..campaign import calibrate_campaign, write_calibration
    from ..io.run_files import read_run
    from ..io.scan_files import read_scan
    from ..model.spatial import build_spatial_model
    from ..report.pipeline import calibration_report, run_report
    from ..rig import load_rig
    from ..simulate.export import write_simulation

    out = Path(out)
    progress("simulating the 'paper' rig (scan and one run)")
    paper = write_simulation(out / "paper", "paper", seed=0)
    progress("simulating the 'campaign' (21 runs)")
    campaign = write_simulation(out / "campaign", "campaign", seed=1,
                                progress=lambda m: progress(f"  simulating {m}"))

    progress("paper: spatial model, forces, report")
    rig = load_rig(paper / "rig.toml")
    scan = read_scan(paper / "scan.uff")
    report = run_report(rig, scan, [read_run(paper / "runs" / "paper.csv")], out / "report",
                        truth_dir=paper / "truth")

    progress("campaign: spatial model")
    crig = load_rig(campaign / "rig.toml")
    cmodel = build_spatial_model(crig, read_scan(campaign / "scan.uff"))
    progress("campaign: forces of every run, then the candidate laws")
    result = calibrate_campaign(crig, cmodel, campaign / "manifest.csv",
                                progress=lambda d, t, n: progress(f"  [{d}/{t}] {n}"))
    write_calibration(result, out / "calibration")
    progress(f"campaign: law {result.law} chosen; its certificate")
    calibration_report(crig, cmodel, result, out / "calibration")
    return report
