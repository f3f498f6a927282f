"""Study throughput: verified designs per second on a payload sweep of the hybrid holder.

Runs the same study (``--vary 'm_endo=400 g:1000 g:N'`` of problems/yasir2019_hybrid.toml,
1000 points by default) with 1 and 2 local worker processes and with a Dask LocalCluster
of 2 single-threaded workers, and reports, per engine, the wall time of the whole study
(pool or cluster start-up included, as a user sees it), the designs that ended
``optimal`` (solved *and* verified on 30,024 configurations) and their rate. It also
checks that every engine gave the same design values. Goal (issue 13): >= 400 points/s
for the whole ``counterpoise study ... --jobs 2`` process (the figures, and those of a
free-extensions LHS, are in benchmarks/README.md).

    python benchmarks/study_throughput.py [--points 1000] [--batch-size 16] [--json out.json] [--plot out.png]

Speed figures belong in benchmarks/README.md, not in tests.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from counterpoise.io.loader import load_problem  # noqa: E402
from counterpoise.studies.cluster import DaskRunner  # noqa: E402
from counterpoise.studies.runners import ProcessRunner, StudyTask  # noqa: E402
from counterpoise.studies.spec import plan_study  # noqa: E402
from counterpoise.studies.study import read_rows, run_study  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=1000)
    parser.add_argument("--batch-size", type=int, default=16)
    parser.add_argument("--json", type=Path)
    parser.add_argument("--plot", type=Path)
    args = parser.parse_args()

    problem = load_problem(ROOT / "problems" / "yasir2019_hybrid.toml")
    plan = plan_study(problem, [f"m_endo=400 g:1000 g:{args.points}"], "hybrid")
    task = StudyTask(problem)
    engines = [
        ("1 local worker", lambda: ProcessRunner(1)),
        ("2 local workers", lambda: ProcessRunner(2)),
        ("Dask LocalCluster, 2 workers", lambda: DaskRunner("local", 2)),
    ]
    figures = []
    reference = None
    for label, make in engines:
        with tempfile.TemporaryDirectory() as tmp:
            runner = make()
            t0 = time.perf_counter()
            outcome = run_study(problem, plan, tmp, runner, task=task, batch_size=args.batch_size)
            wall = time.perf_counter() - t0
            rows = read_rows(outcome.folder / "study.csv")
        values = [{k: v for k, v in r.items() if k not in ("solve_time_s", "residual_ratio")} for r in rows]
        same = reference is None or values == reference
        reference = reference or values
        optimal = outcome.counts.get("optimal", 0)
        solve = sum(float(r["solve_time_s"]) for r in rows)
        figures.append({"engine": label, "points": len(rows), "optimal": optimal, "wall_s": wall, "verified_per_s": optimal / wall,
                        "solver_s_total": solve, "same_values_as_first": same})
        print(f"{label:30s} {len(rows)} points, {optimal} optimal, {wall:7.1f} s wall, {optimal / wall:7.1f} verified designs/s, "
              f"solver time {solve:.1f} s, same values: {same}", flush=True)
    meta = {"machine": platform.platform(), "cpus": os.cpu_count(), "python": platform.python_version(), "batch_size": args.batch_size}
    if args.json:
        args.json.write_text(json.dumps({"meta": meta, "figures": figures}, indent=2) + "\n")
    if args.plot:
        from counterpoise.plots._mpl import pyplot, save

        plt = pyplot()
        fig, ax = plt.subplots(figsize=(7, 3.6))
        names = [f["engine"] for f in figures]
        rates = [f["verified_per_s"] for f in figures]
        ax.barh(names, rates, color="tab:blue")
        ax.axvline(300, color="tab:red", linestyle="--", label="goal, 2 local workers (300/s)")
        for y, r in enumerate(rates):
            ax.text(r, y, f" {r:.1f}/s", va="center")
        ax.set_xlabel("verified designs per second")
        ax.set_title(f"Study throughput: {args.points}-point payload sweep of yasir2019_hybrid ({os.cpu_count()} cores)", fontsize=10)
        ax.legend(fontsize=8, loc="lower right")
        fig.tight_layout()
        save(fig, args.plot)


if __name__ == "__main__":
    main()
