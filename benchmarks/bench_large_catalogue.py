#!/usr/bin/env python3
"""Part choice from a large catalogue: 6000 synthetic parts on two zero-free-length problems.

1. Generates the catalogue with ``scripts/make_spring_catalogue.py --parts 6000 --seed 16``
   (deterministic; written to the work folder, not kept in the repository).
2. Writes ``yasir2019_hybrid_catalogue`` and ``essomba2021_position_catalogue`` with their
   catalogue pointing at it, and times ``counterpoise solve`` on each (whole process).
3. On a subset (the first ``--subset`` parts), compares the screened search (forced by
   ``selection.max_enumeration = 1``) with the enumeration of every rate (exhaustive):
   the chosen parts must be the same.

    .venv/bin/python benchmarks/bench_large_catalogue.py [--repeat 3] [--subset 600]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PROBLEMS = ("yasir2019_hybrid_catalogue", "essomba2021_position_catalogue")
PARTS, SEED = 6000, 16


def with_catalogue(name: str, catalogue: Path, work: Path, suffix: str) -> Path:
    text = (ROOT / "problems" / f"{name}.toml").read_text(encoding="utf-8")
    text = text.replace('file = "shipped"', f'file = "{catalogue.resolve().as_posix()}"')
    path = work / f"{name}{suffix}.toml"
    path.write_text(text, encoding="utf-8")
    return path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--subset", type=int, default=600, help="parts of the exhaustive comparison")
    ap.add_argument("--work", type=Path, default=None)
    args = ap.parse_args(argv)
    work = args.work or Path(tempfile.mkdtemp(prefix="large-catalogue-"))
    work.mkdir(parents=True, exist_ok=True)
    big = work / "large.csv"
    subprocess.run([sys.executable, str(ROOT / "scripts" / "make_spring_catalogue.py"), "--parts", str(PARTS), "--seed", str(SEED), "--out", str(big)], check=True)
    lines = big.read_text(encoding="utf-8").splitlines()
    small = work / "subset.csv"
    small.write_text("\n".join(lines[: args.subset + 1]) + "\n", encoding="utf-8")
    cli = Path(sys.executable).with_name("counterpoise")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT / "src"), os.environ.get("PYTHONPATH", "")]))}
    sys.path.insert(0, str(ROOT / "src"))
    from counterpoise import load_problem
    from counterpoise.selection import PartSearch

    ok = True
    for name in PROBLEMS:
        toml = with_catalogue(name, big, work, "_large")
        times = []
        for _ in range(max(args.repeat, 1)):
            t0 = time.perf_counter()
            done = subprocess.run([str(cli), "solve", str(toml), "--out", str(work / "out")], env=env, capture_output=True, text=True)
            times.append(time.perf_counter() - t0)
            if done.returncode != 0:
                print(done.stdout + done.stderr)
                return 1
        status = (work / "out" / name / "status.txt").read_text(encoding="utf-8")
        search = next(line for line in status.splitlines() if line.startswith("part search"))
        print(f"{name}, {PARTS} parts: whole CLI run {statistics.median(times):.2f} s median ({min(times):.2f}-{max(times):.2f} s); {search}")
        sub = with_catalogue(name, small, work, "_subset")
        exhaustive = PartSearch(load_problem(sub)).run()
        screened = PartSearch(load_problem(sub, {"selection.max_enumeration": 1})).run()
        same = (exhaustive.choice and exhaustive.choice.parts) == (screened.choice and screened.choice.parts)
        ok &= bool(same)
        print(f"  subset of {args.subset} parts: exhaustive {exhaustive.methods} {exhaustive.choice and exhaustive.choice.parts} "
              f"({exhaustive.solves} solves), screened {screened.methods} {screened.choice and screened.choice.parts} ({screened.solves} solves): "
              f"{'same choice' if same else 'DIFFERENT'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
