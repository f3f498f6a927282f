#!/usr/bin/env python3
"""Peer's spring-selection problem (1R arm) over a whole extension-spring catalogue, run
through the product: ``counterpoise solve`` on two problem files, checked independently.

Problem
-------
A 1R arm in a vertical plane, pivot at the origin, x horizontal, y up, at angle phi from
horizontal, phi in [-43.4 deg, +53.6 deg].  Beams of 0.467 kg with their centre of mass at
L/2, an end mass of 0.3272 kg at L = 0.409 m, g = 9.81 m/s^2.  Gravity torque about +z:

    tau_g(phi) = -(m_b L/2 + m_e L) g cos(phi) = -Mg cos(phi),   Mg = 2.2497 N m.

A spring (plus an inextensible cable of length c) runs from a fixed anchor A = (x, y)
(x in [-130, 130] mm, y in [110, 270] mm) to the lever point P = r (cos phi, sin phi) on the
arm (r in [15, 90] mm), c in [0, 300] mm.  Real spring, no pulley: with d = |A - P| the
spring length is s = d - c and the tension is F = F0 + k (s - L0) along P -> A, so

    tau_s = (P x F)_z = F/d * (P x A)_z = F/d * r (y cos phi - x sin phi)     (> 0 lifts).

Net torque tau = tau_g + sum of tau_s.  Writing F = k (d - t) with t = c + L0 - F0/k
("virtual offset"), tau_s = (k - T/d)(P x A)_z with T = k t.

Realisability (what makes a design real), over the WHOLE continuous motion (d_min, d_max in
closed form, not on a grid): r, x, y, c inside their boxes; s = d - c >= L0 (tension only,
no slack); s <= L_max (catalogue ``length_max``); F <= F_max (``load_max``).

Figure of merit: worst-case residual ratio = max_phi |tau| / max_phi |tau_g| on a uniform
grid of ``--grid`` points (default 20001).

Two springs: two of the same part, each with its own r, x, y, c.

What the script does
--------------------
1. Writes the two problem files (one spring; two springs of one slot) into ``--work``, each
   pointing at the catalogue (``--catalogue``, by default ``../shared/catalogues/`` next to the
   repository, read at run time; the catalogue is not redistributable and not in the
   repository).
2. Times ``counterpoise solve`` on each (the whole process, ``--repeat`` runs, median).
3. Reads the chosen part and geometry from ``design.csv`` and re-checks them here with the
   closed-form torque above on a dense grid, and the part's stroke, load and slack over the
   continuous motion: the product's answer is checked by code that shares nothing with it.

Reference results (issue 16): one spring 5108N851 at 0.00300, two springs 5108N735 at
0.000248. The script's former multi-start local search found 8594N153 at 0.001178 for two
springs; the product's screened search finds the better part.
"""

from __future__ import annotations

import argparse
import csv
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

# ----------------------------------------------------------------------------- problem data
M_BEAM, M_END, L_ARM, G = 0.467, 0.3272, 0.409, 9.81
MG = (M_BEAM * L_ARM / 2 + M_END * L_ARM) * G  # N m, gravity torque amplitude
PHI0, PHI1 = np.radians(-43.4), np.radians(53.6)
R_LO, R_HI = 0.015, 0.090
X_LO, X_HI = -0.130, 0.130
Y_LO, Y_HI = 0.110, 0.270
C_MAX = 0.300

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_CATALOGUE = Path("..") / "shared" / "catalogues" / "mcmaster-extension-springs.csv"  # from the repository root
FALLBACK_CATALOGUE = ROOT.parent / "shared" / "catalogues" / "mcmaster-extension-springs.csv"


# ----------------------------------------------------------------------------- catalogue
def load_catalogue(path: Path) -> dict:
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    f = lambda key: np.array([float(r[key]) for r in rows])  # noqa: E731
    k, L0, Lmax, F0, Fmax = f("stiffness"), f("length_natural"), f("length_max"), f("load_min"), f("load_max")
    s_max = np.minimum(Lmax, L0 + (Fmax - F0) / k)  # longest admissible spring length
    f_allow = F0 + k * (s_max - L0)
    t0 = L0 - F0 / k
    return dict(part=[r["part_number"] for r in rows], k=k, L0=L0, F0=F0, t0=t0,
                s_lo=F0 / k, s_hi=f_allow / k, f_allow=f_allow)


# ----------------------------------------------------------------------------- mechanics
def d_extremes(r, x, y):
    """Exact min and max of d(phi) = |A - P(phi)| over the continuous range."""
    rho = np.hypot(x, y)
    th = np.arctan2(y, x)
    e0 = np.sqrt(np.maximum(r * r + rho * rho - 2 * r * (x * np.cos(PHI0) + y * np.sin(PHI0)), 0))
    e1 = np.sqrt(np.maximum(r * r + rho * rho - 2 * r * (x * np.cos(PHI1) + y * np.sin(PHI1)), 0))
    dmin = np.where((th >= PHI0) & (th <= PHI1), np.abs(rho - r), np.minimum(e0, e1))
    dmax = np.where((th - np.pi >= PHI0) & (th - np.pi <= PHI1), rho + r, np.maximum(e0, e1))
    return dmin, dmax


def t_interval(r, x, y, t0, s_lo, s_hi):
    """Feasible virtual offset t for a geometry: t in [t0, t0+c_max], d - t in [s_lo, s_hi]."""
    dmin, dmax = d_extremes(r, x, y)
    return np.maximum(t0, dmax - s_hi), np.minimum(t0 + C_MAX, dmin - s_lo)


def net_torque(k, P, C, S):
    """P (..., ns, 4) = (r, x, y, t) per spring; k (...); returns tau(phi) (..., m) in N m."""
    r, x, y, t = (P[..., i, None] for i in range(4))
    d = np.sqrt(r * r + x * x + y * y - 2 * r * (x * C + y * S))
    tau = (k[..., None, None] * (1 - t / d) * r * (y * C - x * S)).sum(-2)
    return tau - MG * C


def evaluate(cat, i, P, n_grid):
    phi = np.linspace(PHI0, PHI1, n_grid)
    C, S = np.cos(phi), np.sin(phi)
    tau = net_torque(np.array([cat["k"][i]]), P[None], C, S)[0]
    return np.abs(tau).max() / np.abs(MG * C).max()


def feasible(cat, i, P, tol=1e-9):
    ok = True
    for r, x, y, t in P:
        tlo, thi = t_interval(r, x, y, cat["t0"][i], cat["s_lo"][i], cat["s_hi"][i])
        ok &= (R_LO - tol <= r <= R_HI + tol) and (X_LO - tol <= x <= X_HI + tol) and (Y_LO - tol <= y <= Y_HI + tol)
        ok &= tlo - tol <= t <= thi + tol
    return bool(ok)



# ----------------------------------------------------------------------------- problem files
HEAD = """[problem]
name = "{name}"
title = "Peer 1R arm: {title}"

[gravity]
acceleration = "9.81 m/s^2"
direction = [0, -1, 0]

[parameters]
L = "0.409 m"
m_beam = "0.467 kg"
m_end = "0.3272 kg"

[subsystems.arm]
coordinates.phi = {{ range = ["-43.4 deg", "53.6 deg"] }}

[frames.arm]
transforms = [{{ rotate = "z", angle = "phi" }}]

[bodies.beams]
frame = "arm"
mass = "m_beam"
com = ["L/2", 0, 0]
[bodies.end]
frame = "arm"
mass = "m_end"
com = ["L", 0, 0]

[catalogues.vendor]
file = "{catalogue}"
columns = "vendor"

[slots.s]
catalogue = "vendor"
"""

SPRING = """
[variables.r{n}]
lower = "15 mm"
upper = "90 mm"
initial = "50 mm"
[variables.x{n}]
lower = "-130 mm"
upper = "130 mm"
initial = "0 mm"
[variables.y{n}]
lower = "110 mm"
upper = "270 mm"
initial = "200 mm"
[variables.c{n}]
lower = "0 mm"
upper = "300 mm"
initial = "0 mm"

[springs.s{n}]
slot = "s"
mount = "direct"
cable = "c{n}"
from = {{ frame = "ground", point = ["x{n}", "y{n}", 0] }}
to = {{ frame = "arm", point = ["r{n}", 0, 0] }}
"""

CASES = {1: ("peer_1r_arm_1spring", "one directly attached catalogue spring"), 2: ("peer_1r_arm_2springs", "two springs of one catalogue part")}


def problem_text(springs: int, catalogue: Path) -> str:
    name, title = CASES[springs]
    return HEAD.format(name=name, title=title, catalogue=catalogue.resolve().as_posix()) + "".join(SPRING.format(n=n) for n in range(1, springs + 1))


def counterpoise_command() -> list[str]:
    """The CLI of the interpreter running this script (the project's venv), else the one on PATH."""
    here = Path(sys.executable).with_name("counterpoise")
    return [str(here)] if here.exists() else [shutil.which("counterpoise") or "counterpoise"]


def read_design(folder: Path, springs: int) -> tuple[str, np.ndarray, str]:
    """(part number, (springs, 4) array of r, x, y, c in m, status) from the product's output."""
    with open(folder / "design.csv", newline="", encoding="utf-8") as fh:
        rows = {r["name"]: r for r in csv.DictReader(fh)}
    scale = {"mm": 1e-3, "m": 1.0}
    values = np.array([[float(rows[f"{v}{n}"]["value"]) * scale[rows[f"{v}{n}"]["unit"]] for v in "rxyc"] for n in range(1, springs + 1)])
    with open(folder / "summary.csv", newline="", encoding="utf-8") as fh:
        status = next(csv.DictReader(fh))["status"]
    return rows["s"]["value"], values, status


# ----------------------------------------------------------------------------- main
def check(cat: dict, part: str, rxyc: np.ndarray, n_grid: int) -> tuple[float, bool]:
    """The independent figure of merit and realisability of the product's design."""
    i = cat["part"].index(part)
    P = rxyc.copy()
    P[:, 3] = rxyc[:, 3] + cat["t0"][i]  # t = c + L0 - F0/k
    return evaluate(cat, i, P, n_grid), feasible(cat, i, P, tol=1e-7)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--catalogue", type=Path, default=None, help="vendor catalogue CSV (SI columns); default ../shared/catalogues/")
    ap.add_argument("--work", type=Path, default=None, help="folder for the problem files and outputs (default: a temporary one)")
    ap.add_argument("--repeat", type=int, default=3, help="timed runs of each case (median reported)")
    ap.add_argument("--grid", type=int, default=20001, help="phi grid points of the independent check")
    ap.add_argument("--out", type=Path, help="write the results to this CSV")
    args = ap.parse_args(argv)
    path = args.catalogue or next((p for p in (Path.cwd() / DEFAULT_CATALOGUE, FALLBACK_CATALOGUE) if p.exists()), FALLBACK_CATALOGUE)
    if not path.exists():
        print(f"catalogue {path} not found: pass --catalogue (the vendor's table is not in the repository)")
        return 0
    cat = load_catalogue(path)
    work = args.work or Path(tempfile.mkdtemp(prefix="peer-1r-arm-"))
    work.mkdir(parents=True, exist_ok=True)
    command = counterpoise_command()
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT / "src"), os.environ.get("PYTHONPATH", "")]))}
    results = []
    for springs in (1, 2):
        name = CASES[springs][0]
        toml = work / f"{name}.toml"
        toml.write_text(problem_text(springs, path), encoding="utf-8")
        times = []
        for _ in range(max(args.repeat, 1)):
            t0 = time.perf_counter()
            done = subprocess.run([*command, "solve", str(toml), "--out", str(work / "out")], env=env, capture_output=True, text=True)
            times.append(time.perf_counter() - t0)
            if done.returncode != 0:
                print(done.stdout + done.stderr)
                return 1
        part, rxyc, status = read_design(work / "out" / name, springs)
        ratio, ok = check(cat, part, rxyc, args.grid)
        results.append((springs, part, ratio, ok, status, statistics.median(times), min(times), max(times)))
        print(f"{springs} spring(s): {part}, worst residual ratio {ratio:.6f} on {args.grid} points (independent check), "
              f"within stroke/load/slack: {ok}, status {status}; whole CLI run {statistics.median(times):.2f} s median "
              f"({min(times):.2f}-{max(times):.2f} s, {len(times)} runs)")
    if args.out:
        with open(args.out, "w", newline="", encoding="utf-8") as fh:
            w = csv.writer(fh)
            w.writerow(["springs", "part_number", "worst_residual_ratio", "realisable", "status", "median_s", "min_s", "max_s"])
            w.writerows(results)
    return 0 if all(r[3] for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
