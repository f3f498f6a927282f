"""Compare two ``study.csv`` files: the same rows, every cell equal to 1e-9 relative except timings.

A change meant to make studies faster must not change their results. Run the same study
with the state before and after (e.g. a checkout of ``main`` with its own venv) and compare::

    python benchmarks/compare_studies.py BEFORE/yasir2019_hybrid-study/study.csv AFTER/yasir2019_hybrid-study/study.csv

Prints the largest relative difference per column and exits 1 when a cell differs by more
than ``--rtol`` (default 1e-9) or a text cell (status, certificate, solver, message) differs.
``solve_time_s`` is skipped (a timing). ``residual_ratio`` is compared like every other
column: for a balanced design it is rounding noise (~1e-15), so it agrees only when the
arithmetic is the same, bit for bit.
"""

from __future__ import annotations

import argparse
import csv
import sys

TIMINGS = {"solve_time_s"}


def compare(before: str, after: str, rtol: float = 1e-9) -> tuple[dict[str, float], list[str]]:
    """(largest relative difference per column, descriptions of the cells that differ)."""
    with open(before, encoding="utf-8", newline="") as a, open(after, encoding="utf-8", newline="") as b:
        rows_a, rows_b = list(csv.DictReader(a)), list(csv.DictReader(b))
    problems: list[str] = []
    if len(rows_a) != len(rows_b):
        return {}, [f"{len(rows_a)} rows against {len(rows_b)}"]
    if rows_a and list(rows_a[0]) != list(rows_b[0]):
        return {}, ["the columns differ"]
    worst: dict[str, float] = {}
    for ra, rb in zip(rows_a, rows_b):
        for column, x in ra.items():
            y = rb[column]
            if column in TIMINGS or x == y:
                continue
            try:
                fx, fy = float(x), float(y)
            except ValueError:
                problems.append(f"point {ra.get('point')}: {column}: {x!r} against {y!r}")
                continue
            relative = abs(fx - fy) / max(abs(fx), abs(fy), 1e-300)
            worst[column] = max(worst.get(column, 0.0), relative)
            if not relative <= rtol:
                problems.append(f"point {ra.get('point')}: {column}: {x} against {y} (relative {relative:.2e})")
    return worst, problems


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("before")
    parser.add_argument("after")
    parser.add_argument("--rtol", type=float, default=1e-9)
    args = parser.parse_args(argv)
    worst, problems = compare(args.before, args.after, args.rtol)
    for line in problems[:20]:
        print(line)
    print("largest relative differences:", {k: f"{v:.2e}" for k, v in worst.items()} or "none (identical but for timings)")
    print("same results" if not problems else f"{len(problems)} cells differ")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
