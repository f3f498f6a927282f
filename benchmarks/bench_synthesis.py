"""`counterpoise synthesise` on planar arms of 2 to N links (springs between every pair of
bodies, a 5 x 5 grid on the ground plate, 25 grid points along each link): the whole
command in a fresh process, its wall and CPU time, the least cost and the number of grid
and master solves (from status.txt). Usage: python benchmarks/bench_synthesis.py [N] [REPEATS]

The arms are the ones of problems/synthesis/arm{3,4}_springs.toml (written here by
:func:`arm`): link i of mass (n + 1 - i)/2 kg, 300 mm long, centre of mass at 150 mm.
"""

from __future__ import annotations

import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CLI = ROOT / ".venv" / "bin" / "counterpoise"


def arm(n: int, points: int = 5) -> str:
    """The problem file of an n-link arm with springs between every pair of bodies."""
    out = [f'[problem]\nname = "arm{n}_springs"\n\n[gravity]\nacceleration = "9.81 m/s^2"\ndirection = [0, -1, 0]\n\n[parameters]\nl = "300 mm"\nc = "150 mm"\n']
    out += [f'm{i} = "{(n + 1 - i) * 0.5:g} kg"\n' for i in range(1, n + 1)]
    out.append("\n[subsystems.arm]\n")
    out += [f'coordinates.q{i} = {{ range = ["-180 deg", "180 deg"] }}\n' for i in range(1, n + 1)]
    for i in range(1, n + 1):
        parent = "" if i == 1 else f'parent = "link_{i - 1}"\n'
        move = '{ rotate = "z", angle = "q1" }' if i == 1 else f'{{ translate = ["l", 0, 0] }}, {{ rotate = "z", angle = "q{i}" }}'
        out.append(f"\n[frames.link_{i}]\n{parent}transforms = [{move}]\n")
        out.append(f'\n[bodies.link_{i}]\nframe = "link_{i}"\nmass = "m{i}"\ncom = ["c", 0, 0]\n')
    out.append(f'\n[synthesis]\nsprings = "all"\nmax_rate = "50 N/mm"\npoints = {points}\n')
    out.append('\n[synthesis.regions.ground]\nbox = { lower = ["-200 mm", "0 mm", 0], upper = ["200 mm", "400 mm", 0] }\n')
    for i in range(1, n + 1):
        out.append(f'\n[synthesis.regions.link_{i}]\nsegment = [["-150 mm", 0, 0], ["300 mm", 0, 0]]\npoints = {points * points}\n')
    return "".join(out)


def run(n: int, folder: Path) -> tuple[float, float, str]:
    path = folder / f"arm{n}.toml"
    path.write_text(arm(n), encoding="utf-8")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run([str(CLI), "synthesise", str(path), "--out", str(folder / "out")], capture_output=True, text=True, env={**os.environ, "COUNTERPOISE_PROGRESS": "0"})
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    status = (folder / "out" / f"arm{n}_springs-synthesis" / "status.txt")
    text = status.read_text() if status.exists() else done.stdout + done.stderr
    cost = re.search(r"least cost on the grid: (\S+)", text)
    solves = re.search(r"(\d+) candidates, (\d+) master and (\d+) grid solves", text)
    what = f"cost {cost.group(1) if cost else '?'}, " + (f"{solves.group(1)} candidates, {solves.group(2)} master / {solves.group(3)} grid solves" if solves else text.strip()[:200])
    return wall, cpu, what


def main() -> None:
    largest = int(sys.argv[1]) if len(sys.argv) > 1 else 4
    repeats = int(sys.argv[2]) if len(sys.argv) > 2 else 3
    print(f"load {os.getloadavg()[0]:.2f}")
    with tempfile.TemporaryDirectory() as tmp:
        for n in range(2, largest + 1):
            results = [run(n, Path(tmp)) for _ in range(repeats)]
            walls = sorted(r[0] for r in results)
            cpus = sorted(r[1] for r in results)
            print(f"{n} links: wall {walls[len(walls) // 2]:.2f} s ({walls[0]:.2f}-{walls[-1]:.2f}), CPU {cpus[len(cpus) // 2]:.2f} s; {results[0][2]}", flush=True)


if __name__ == "__main__":
    main()
