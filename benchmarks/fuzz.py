"""The long fuzz run: thousands of mutated inputs through every command.

Run from the project root::

    .venv/bin/python benchmarks/fuzz.py              # 3000 cases (200 per input kind)
    .venv/bin/python benchmarks/fuzz.py --cases 500  # fewer
    .venv/bin/python benchmarks/fuzz.py --kinds rig-keys model-keys cal-keys --cases 150

Builds the small 'paper' lab of ``tests/fuzz_inputs.py`` once, then draws ``--cases`` cases
spread evenly over the input kinds (seeds ``--start`` onwards, so a run is reproducible),
runs each through ``forcecal.cli.main`` and classifies it: ok, refused, unclean (a refusal not
in the promised form), internal (exit 1 or an exception), silent (exit 0 with non-finite or
absurd outputs; for the key kinds, a key misspelt, in the wrong case, moved, an unknown table
or a key written twice, exit 0 at all, and a refusal must name the key). Prints a table of
counts per outcome and input kind, the first examples of each failure, and writes
``benchmarks/results/fuzz.json``.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from collections import Counter  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from fuzz_inputs import KINDS, OUTCOMES, build_lab, fuzz_one  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results" / "fuzz.json"


def table(counts: Counter, kinds: list[str]) -> str:
    """Counts per input kind (rows) and outcome (columns), with totals."""
    head = f"{'input kind':<12}" + "".join(f"{o:>10}" for o in OUTCOMES) + f"{'total':>10}"
    lines = [head, "-" * len(head)]
    for kind in [*kinds, "all"]:
        row = [sum(counts[(k, o)] for k in kinds) if kind == "all" else counts[(kind, o)]
               for o in OUTCOMES]
        if kind == "all":
            lines.append("-" * len(head))
        lines.append(f"{kind:<12}" + "".join(f"{n:>10}" for n in row) + f"{sum(row):>10}")
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=200 * len(KINDS),
                        help=f"cases in all (default {200 * len(KINDS)})")
    parser.add_argument("--start", type=int, default=0, help="first seed (default 0)")
    parser.add_argument("--kinds", nargs="*", default=list(KINDS), help="input kinds")
    parser.add_argument("--examples", type=int, default=4,
                        help="failures shown per outcome and kind (default 4)")
    parser.add_argument("--output", default=str(RESULTS), help="JSON results file")
    args = parser.parse_args()
    kinds = list(args.kinds)
    start = time.perf_counter()
    counts: Counter = Counter()
    failures: list[dict] = []
    with tempfile.TemporaryDirectory(prefix="forcecal-fuzz-") as tmp:
        lab = build_lab(Path(tmp) / "lab")
        per_kind = max(1, args.cases // len(kinds))
        for i in range(per_kind):
            for kind in kinds:
                o = fuzz_one(lab, Path(tmp) / "work", kind, args.start + i)
                counts[(kind, o.outcome)] += 1
                if o.outcome not in ("ok", "refused"):
                    failures.append(vars(o))
            if (i + 1) % max(1, per_kind // 10) == 0:
                print(f"  {i + 1}/{per_kind} per kind, {time.perf_counter() - start:.0f} s",
                      file=sys.stderr, flush=True)
    elapsed = time.perf_counter() - start
    print(table(counts, kinds))
    print(f"\n{sum(counts.values())} cases in {elapsed:.0f} s")
    shown: Counter = Counter()
    for f in failures:
        key = (f["outcome"], f["kind"])
        if shown[key] < args.examples:
            shown[key] += 1
            print(f"{f['outcome']:>8} {f['kind']:<11} seed {f['seed']:<5} {f['what'][:60]!s:<60}"
                  f" -> {f['detail'][:200]}")
    doc = {
        "cases": sum(counts.values()),
        "seconds": round(elapsed, 1),
        "start_seed": args.start,
        "counts": {k: {o: counts[(k, o)] for o in OUTCOMES} for k in kinds},
        "totals": {o: sum(counts[(k, o)] for k in kinds) for o in OUTCOMES},
        "failures": failures,
    }
    out = Path(args.output)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    bad = doc["totals"]["internal"] + doc["totals"]["silent"]
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
