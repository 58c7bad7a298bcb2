"""The mistake campaign of issue 34: one plausible lab mistake at a time on the virtual rig.

Run from the project root::

    .venv/bin/python benchmarks/mistakes.py                 # every mistake, seed 0
    .venv/bin/python benchmarks/mistakes.py --seeds 0 1 2   # more seeds
    .venv/bin/python benchmarks/mistakes.py --mistakes "gauge scale +2%" "no tare"
    .venv/bin/python benchmarks/mistakes.py --clean-seeds 30    # false alarms on clean labs

Builds each lab of ``tests/mistakes.py`` once per seed (``forcecal simulate``, ``forcecal
scan``), makes every mistake of :data:`mistakes.MISTAKES` on its presets (the rig, the run, the
tare or the scan edited; ``forcecal reconstruct`` run through ``forcecal.cli.main``) and judges
each: refused, noted (a new note names the cause), wrong note (a new note blames another
sensor), harmless (every force within 3x its stated uncertainty, or within 1.5x the clean run's
error), silently wrong. Errors are against the simulator's truth, DC included, in % of the true
total's AC RMS; error/stated is the worst force's (or the total's) RMS error over its RMS
stated standard uncertainty. Prints the clean baselines, the table and the counts per verdict,
and writes ``benchmarks/results/mistakes.json``.

``--clean-seeds N`` (instead of the campaign) counts the self-checks' false alarms: it builds
each lab of :data:`FALSE_ALARM_LABS` at seeds 1..N, reconstructs every clean run of its
``runs/`` folder (the tares aside; one ``forcecal reconstruct`` per lab), sorts every note by
the check that wrote it (:data:`CHECKS`), prints the alarms per check and lab and each check's
rate per run with its Clopper-Pearson 95 % interval, and writes
``benchmarks/results/false_alarms.json``.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import csv  # noqa: E402
import json  # noqa: E402
import re  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from collections import Counter  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from mistakes import (  # noqa: E402
    K_BOUND,
    LABS,
    MISTAKES,
    VERDICTS,
    Lab,
    Result,
    build_lab,
    campaign,
    quiet_main,
)

RESULTS = Path(__file__).resolve().parent / "results" / "mistakes.json"
FALSE_ALARMS = RESULTS.with_name("false_alarms.json")
NOTE_CHARS = 100
FALSE_ALARM_LABS = ("paper", "paper-lab", "paper-noflux", "tilt", "campaign")
"""The labs of ``--clean-seeds``: ideal sensors; lab realism with a tare, with and without a
flux channel; unequal gaps; a campaign's gaps and currents against one scan."""
CHECKS = (
    ("flux", ("Maxwell force",)),
    ("pole", ("pull unalike",)),
    ("scan", ("the scan's motion per unit",)),
    ("misfit", ("disagree with the scan model's shape",)),
    ("pull-only", ("pushes",)),
    ("weight", ("where the rig's masses weigh",)),
    ("dc", ("far from the",)),
    ("drift", ("drifts", "drift")),
    ("info", ("mains",)),
    ("dropped", ("leave them out",)),
    ("scale", ("the inertia's scale is not taken",)),
    ("info", ("calibrated in situ", "the inertia's scale is not estimated",
              "the rig declares none", "type-B", "no shape in the scan model",
              "short-time Wiener gains", "the reactions carry the inertia",
              "above the scan's band", "the scan's noise makes")),
    ("span", ("load differs from every scan",)),
)
"""Which check wrote a note: the first whose phrases the note holds (else ``other``)."""
ALARMS = ("flux", "pole", "scan", "misfit", "pull-only", "dc", "drift", "dropped", "scale",
          "other")
"""The checks whose notes are alarms (``info`` and ``span`` only inform: a harmonic near the
mains', one without a shape, the type-B sources the rig leaves out, a load between the scans';
under any drive, what the smoother lets through, the reactions' transfer, a force above the
scan's band, the scan's share of the variance, the inertia's scale calibrated in situ or not
estimated without a flux channel). ``scale``: the inertia's scale refused (the flux does not
explain the estimate, or the scale lies beyond the declared uncertainties)."""
COLUMNS = (*ALARMS, "info", "span")


def _num(x: float, fmt: str = ".3g") -> str:
    return "-" if x != x else format(x, fmt)


def row(r: Result) -> str:
    """One table row: mistake, lab, verdict, errors, error/stated, the note or refusal."""
    text = r.message if r.verdict == "refused" else r.relevant_note
    text = re.sub(r"^(forcecal: )?(run '[^']*': )?", "", text.replace("\n", " "))[:NOTE_CHARS]
    return (f"{r.mistake:<24} {r.lab:<14} {r.seed:>4} {r.verdict:<15} "
            f"{_num(r.total_error_pct):>8} {_num(r.worst_force_error_pct):>8} "
            f"{_num(r.error_over_stated):>9}  {text}")


HEADER = (f"{'mistake':<24} {'lab':<14} {'seed':>4} {'verdict':<15} {'total %':>8} "
          f"{'force %':>8} {'err/std':>9}  note (or refusal), first {NOTE_CHARS} characters")


def baseline_lines(labs: list[Lab]) -> list[str]:
    lines = [f"{'lab':<14} {'seed':>4} {'f0 Hz':>9} {'total %':>8} {'force %':>8} "
             f"{'err/std':>8} {'H>=2 %':>7}  clean notes"]
    for lab in labs:
        c = lab.clean
        assert c is not None
        lines.append(f"{lab.name:<14} {lab.seed:>4} {c.f0:>9.5f} {c.total_error_pct:>8.3f} "
                     f"{c.worst_force_error_pct:>8.3f} {c.error_over_stated:>8.2f} "
                     f"{lab.higher_harmonics_share():>7.2f}  {len(c.all_notes)}")
    return lines


def check_of(note: str) -> str:
    """The check that wrote ``note`` (see :data:`CHECKS`)."""
    return next((name for name, phrases in CHECKS if any(p in note for p in phrases)), "other")


def clean_runs(lab: Lab) -> list[Path]:
    """Every run of the lab's ``runs/`` folder that its manifest does not call a tare."""
    if lab.spec.only_run:
        return [lab.root / "runs" / f"{lab.spec.run}.csv"]
    manifest = lab.root / "manifest.csv"
    if manifest.exists():
        rows = list(csv.DictReader(manifest.read_text(encoding="utf-8").splitlines()))
        return sorted(lab.root / r["run"] for r in rows if r["tare"].lower() != "true")
    return sorted(p for p in (lab.root / "runs").glob("*.csv") if p.stem != lab.spec.tare)


def survey_lab(lab: Lab) -> list[dict]:
    """Reconstruct every clean run of ``lab`` in one call: a record per run with its notes
    (and the warnings that name it), each with the check that wrote it."""
    runs = clean_runs(lab)
    out = lab.root / "survey"
    tare = [] if lab.spec.tare is None else ["--tare", lab.root / "runs" / f"{lab.spec.tare}.csv"]
    code, err = quiet_main(["reconstruct", lab.root / "rig.toml", lab.model, *runs, "-o", out,
                            *tare])
    warned = [line for line in err.splitlines() if line.startswith("forcecal: warning:")]
    records = []
    for run in runs:
        doc = out / f"{run.stem}.json"
        record = {"lab": lab.name, "seed": lab.seed, "run": run.stem, "code": code,
                  "refused": None, "notes": []}
        if not doc.exists():
            record["refused"] = err.strip().splitlines()[-1] if err.strip() else f"exit {code}"
            records.append(record)
            continue
        notes = json.loads(doc.read_text(encoding="utf-8")).get("notes", [])
        notes += [w for w in warned if f"'{run.stem}" in w or f"{run.stem}.csv" in w]
        record["notes"] = [{"check": check_of(n), "text": n.replace(str(lab.root), "LAB")}
                           for n in notes]
        records.append(record)
    return records


def simulator_draws(lab: Lab) -> dict:
    """What the simulator drew for the lab (sensitivities, offsets, drifts), if it drew."""
    doc = json.loads((lab.root / "truth" / "simulator.json").read_text(encoding="utf-8"))
    realism = doc.get("realism") or {}
    return {k: v for k, v in realism.items() if k not in ("settings", "scans")}


def survey(seeds: list[int], labs: tuple[str, ...] = FALSE_ALARM_LABS,
           progress: bool = True) -> tuple[list[dict], dict]:
    """Every clean run's notes of ``labs`` at ``seeds``, and the draws."""
    records: list[dict] = []
    draws: dict[str, dict] = {}
    for seed in seeds:
        start = time.perf_counter()
        for name in labs:
            with tempfile.TemporaryDirectory() as tmp:
                lab = build_lab(name, seed, Path(tmp))
                got = survey_lab(lab)
                draws[f"{name}/{seed}"] = simulator_draws(lab)
            records += got
            for r in got:
                for n in r["notes"]:
                    if progress and n["check"] in ALARMS:
                        print(f"  alarm {name} seed {seed} {r['run']} [{n['check']}]: "
                              f"{n['text'][:200]}", flush=True)
        if progress:
            print(f"seed {seed}: {time.perf_counter() - start:.0f} s", flush=True)
    return records, draws


def alarm_counts(records: list[dict]) -> dict[str, int]:
    """Runs with at least one note of each check (``any``: of any alarm; ``refused``)."""
    counts = dict.fromkeys((*COLUMNS, "any", "refused"), 0)
    for r in records:
        checks = {n["check"] for n in r["notes"]}
        for c in checks:
            counts[c] += 1
        counts["any"] += bool(checks & set(ALARMS))
        counts["refused"] += r["refused"] is not None
    return counts


def clopper_pearson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """The exact (Clopper-Pearson) interval of a binomial rate, k of n."""
    from scipy.stats import beta

    a = (1 - level) / 2
    low = 0.0 if k == 0 else float(beta.ppf(a, k, n - k + 1))
    high = 1.0 if k == n else float(beta.ppf(1 - a, k + 1, n - k))
    return low, high


def false_alarm_lines(records: list[dict]) -> tuple[list[str], dict]:
    """The table (runs with an alarm per check and lab, rate per run) and the totals."""
    labs = list(dict.fromkeys(r["lab"] for r in records))
    cols = (*COLUMNS, "any", "refused")
    lines = [f"{'lab':<10} {'runs':>5} " + " ".join(f"{c:>9}" for c in cols)
             + f" {'rate/run':>9}"]
    for name in [*labs, "total"]:
        mine = [r for r in records if name in ("total", r["lab"])]
        c = alarm_counts(mine)
        lines.append(f"{name:<10} {len(mine):>5} " + " ".join(f"{c[k]:>9}" for k in cols)
                     + f" {c['any'] / max(len(mine), 1):>9.3g}")
    counts, n = alarm_counts(records), len(records)
    totals = {}
    lines.append(f"\n{'check':<10} {'alarms':>6} {'runs':>5} {'rate':>9}  95 % interval "
                 "(Clopper-Pearson)")
    for check in (*ALARMS, "any"):
        low, high = clopper_pearson(counts[check], n)
        totals[check] = {"alarms": counts[check], "runs": n, "rate": counts[check] / n,
                         "interval_95": [low, high]}
        lines.append(f"{check:<10} {counts[check]:>6} {n:>5} {counts[check] / n:>9.3g}  "
                     f"[{low:.3g}, {high:.3g}]")
    return lines, {"by_lab": {name: alarm_counts([r for r in records if r["lab"] == name])
                              for name in labs}, "totals": totals}


def false_alarms(seeds: list[int], out: Path, merge: list[Path] | None = None,
                 labs: tuple[str, ...] = FALSE_ALARM_LABS) -> int:
    """``--clean-seeds``: the survey, its table and ``out``; ``--merge``: the surveys of
    earlier ``--clean-seeds`` runs (their seeds apart) in one table."""
    import forcecal
    from forcecal.forces.crosschecks import FALSE_ALARM

    start = time.perf_counter()
    if merge:
        docs = [json.loads(p.read_text(encoding="utf-8")) for p in merge]
        seeds = sorted(s for d in docs for s in d["seeds"])
        records = [{**r, "notes": [{**n, "check": check_of(n["text"])} for n in r["notes"]]}
                   for d in docs for r in d["runs"]]
        draws = {k: v for d in docs for k, v in d["simulator_draws"].items()}
        elapsed = sum(d["elapsed_s"] for d in docs)
    else:
        records, draws = survey(seeds, labs)
        elapsed = time.perf_counter() - start
    lines, counts = false_alarm_lines(records)
    print(f"\nfalse alarms on clean runs, seeds {seeds[0]}..{seeds[-1]} (runs with a note of "
          f"each check; the checks' stated rate: {FALSE_ALARM:g} per run); {elapsed:.0f} s")
    print("\n".join(lines))
    doc = {"forcecal": {"version": forcecal.__version__,
                        "source": str(Path(forcecal.__file__).resolve().parent)},
           "seeds": seeds, "labs": list(dict.fromkeys(r["lab"] for r in records)),
           "elapsed_s": elapsed,
           "stated_rate": {"flux": FALSE_ALARM}, "checks": {k: list(v) for k, v in CHECKS},
           "alarms": list(ALARMS), **counts, "simulator_draws": draws, "runs": records}
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    print(f"wrote {out}")
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0], help="seeds (default 0)")
    parser.add_argument("--labs", nargs="+", default=None, choices=list(LABS),
                        help="labs (default: every lab a chosen mistake uses)")
    parser.add_argument("--mistakes", nargs="+", default=None, help="mistakes by name")
    parser.add_argument("--clean-seeds", type=int, default=0, metavar="N",
                        help="instead of the campaign, count the false alarms on the clean "
                        f"runs of {', '.join(FALSE_ALARM_LABS)} at seeds 1..N (default 0: off)")
    parser.add_argument("--first-seed", type=int, default=1, metavar="K",
                        help="with --clean-seeds, seeds K..K+N-1 (default 1)")
    parser.add_argument("--merge", nargs="+", default=None, metavar="JSON",
                        help="instead, one table of earlier --clean-seeds surveys")
    parser.add_argument("--out", default=None, help="the JSON to write (default "
                        f"{RESULTS.name}, or {FALSE_ALARMS.name} with --clean-seeds)")
    args = parser.parse_args()
    if args.merge:
        return false_alarms([], Path(args.out or FALSE_ALARMS), [Path(p) for p in args.merge])
    if args.clean_seeds > 0:
        return false_alarms(list(range(args.first_seed, args.first_seed + args.clean_seeds)),
                            Path(args.out or FALSE_ALARMS), labs=tuple(args.labs or
                                                                     FALSE_ALARM_LABS))
    args.out = args.out or str(RESULTS)
    chosen = tuple(m for m in MISTAKES if args.mistakes is None or m.name in args.mistakes)
    wanted = args.labs or sorted({p for m in chosen for p in m.presets})
    start = time.perf_counter()
    results: list[Result] = []
    built: list[Lab] = []
    print(HEADER)
    print("-" * len(HEADER))
    with tempfile.TemporaryDirectory() as tmp:
        for seed in args.seeds:
            labs = {name: build_lab(name, seed, Path(tmp)) for name in wanted}
            built += labs.values()
            results += campaign(labs, chosen, progress=lambda r: print(row(r), flush=True))
    counts = Counter(r.verdict for r in results)
    elapsed = time.perf_counter() - start
    print("\nclean baselines (errors in % of the true total's AC RMS; H>=2 %: the true total's "
          "harmonics above the fundamental, % of its AC RMS)")
    print("\n".join(baseline_lines(built)))
    print("\ncounts: " + ", ".join(f"{v} {counts[v]}" for v in VERDICTS)
          + f" (of {len(results)}); {elapsed:.0f} s")
    silent_beyond = sum(r.verdict == "silently wrong" and r.error_over_stated > K_BOUND
                        for r in results)
    print(f"silently wrong beyond {K_BOUND:g}x the stated uncertainty: {silent_beyond}")
    import forcecal

    doc = {"forcecal": {"version": forcecal.__version__,
                        "source": str(Path(forcecal.__file__).resolve().parent)},
           "seeds": args.seeds, "k_bound": K_BOUND, "elapsed_s": elapsed,
           "counts": {v: counts[v] for v in VERDICTS},
           "baselines": [{**lab.clean.to_json(), "higher_harmonics_pct":
                          lab.higher_harmonics_share()} for lab in built if lab.clean],
           "mistakes": {m.name: {"what": m.what, "presets": list(m.presets),
                                 "channels": list(m.channels), "words": list(m.words)}
                        for m in chosen},
           "results": [r.to_json() for r in results]}
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
