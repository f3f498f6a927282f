#!/usr/bin/env python3
"""Generate the catalogue of helical extension springs shipped with counterpoise.

Every row is computed from the spring design formulas of Shigley's Mechanical
Engineering Design, chapter 10 ("Mechanical Springs", extension springs), as
coded once in ``counterpoise.springs`` (materials and physics); no row is taken
from a vendor catalogue, so its part numbers cannot be bought.  See
``docs/spring-catalogue.md`` for the schema and the assumptions and
``docs/springs.md`` for the formulas.

Usage::

    python scripts/make_spring_catalogue.py            # (re)write the CSV
    python scripts/make_spring_catalogue.py --check    # exit 1 if the CSV is stale
    python scripts/make_spring_catalogue.py --out other.csv
    python scripts/make_spring_catalogue.py --parts 6000 --out big.csv   # large synthetic catalogue

The output is deterministic: a fixed design grid, a fixed iteration order and
values written with 6 significant digits.  Part numbers are assigned in grid
order, so they stay the same from run to run as long as the grid below is not
changed (append new grid entries at the end of ``GRID`` to keep existing
numbers).

Needs counterpoise installed (the venv); otherwise standard library + numpy.
"""

from __future__ import annotations

import argparse
import csv
import io
import math
import sys
from pathlib import Path

import numpy as np

from counterpoise.springs import physics as ph
from counterpoise.springs.materials import Material, material

REPO_ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OUT = REPO_ROOT / "src" / "counterpoise" / "data" / "extension_springs.csv"

COLUMNS = (
    "part_number",
    "rate_N_per_m",
    "free_length_m",
    "initial_tension_N",
    "max_load_N",
    "max_length_m",
    "outer_diameter_m",
    "wire_diameter_m",
    "material",
    "mass_kg",
    "price_eur",
    "rate_tolerance",
    "initial_tension_tolerance",
)

RATE_TOLERANCE = 0.10  # +/- fraction of the nominal rate
INITIAL_TENSION_TOLERANCE = 0.20  # +/- fraction of the nominal initial tension
SIG_DIGITS = 6  # significant digits written to the CSV


MUSIC_WIRE = material("music_wire")
STAINLESS_302 = material("stainless_302")

#: EUR/kg of wire, illustrative only (the price model below)
PRICE_PER_KG = {MUSIC_WIRE.key: 15.0, STAINLESS_302.key: 40.0}

# Design grid: (material, wire diameters in mm, spring indices C = D/d, body coil counts).
# Wire diameters are preferred metric sizes (Shigley table A-17 style).
GRID = (
    (
        MUSIC_WIRE,
        (0.30, 0.35, 0.40, 0.45, 0.50, 0.60, 0.70, 0.80, 0.90, 1.00,
         1.10, 1.20, 1.40, 1.60, 1.80, 2.00, 2.20, 2.50, 2.80, 3.00),
        (5.0, 6.0, 8.0, 10.0, 12.0),
        (6, 12, 24, 48, 96),
    ),
    (
        STAINLESS_302,
        (0.40, 0.50, 0.60, 0.80, 1.00, 1.20, 1.40, 1.60, 1.80, 2.00, 2.50, 3.00),
        (6.0, 8.0, 10.0),
        (10, 20),
    ),
)


# Illustrative price model (NOT a quotation): a fixed set-up share, a per-coil
# forming cost (hooks counted as one coil each) and the wire material cost.
PRICE_BASE_EUR = 0.50
PRICE_PER_COIL_EUR = 0.02


def _rows_for(mat: Material, d: np.ndarray, C: np.ndarray, Nb: np.ndarray) -> tuple[list[dict[str, object]], int]:
    """Rows (without part numbers) for wire diameters d (m), spring indices C and body coil
    counts Nb of one material, and the number of rejected candidates."""
    rows: list[dict[str, object]] = []
    rejected = 0
    D = C * d  # mean coil diameter, m

    # Active coils: body coils plus the hook contribution G/E, and the rate.
    Na = ph.active_coils(mat, d, Nb)
    k = ph.rate(mat, d, D, Na)

    # Maximum load from the allowable body shear stress (K_B corrected).
    tau_allow = mat.body_torsion * ph.tensile_strength(mat, d)
    F_max = ph.force_at_shear(tau_allow, d, D, C)

    # Initial tension from the middle of the preferred initial-stress band.
    F0 = ph.tension_of_stress(ph.initial_stress_mid(C), d, D)

    # Free length inside two full machine hooks, and the length at the maximum load.
    L0 = ph.free_length(d, D, Nb)
    L_max = L0 + (F_max - F0) / k

    # Mass: body coils plus each hook counted as one coil of mean diameter D.
    mass = ph.mass(mat, d, D, Nb)

    price = PRICE_BASE_EUR + PRICE_PER_COIL_EUR * (Nb + 2.0) + PRICE_PER_KG[mat.key] * mass

    for i in range(d.size):
        values = (k[i], L0[i], F0[i], F_max[i], L_max[i], D[i] + d[i], d[i], mass[i], price[i])
        ok = (
            all(math.isfinite(float(v)) and v > 0 for v in values)
            and ph.C_MIN <= C[i] <= ph.C_MAX
            and F_max[i] > F0[i]
            and L_max[i] > L0[i]
        )
        if not ok:
            rejected += 1
            continue
        rows.append(
            {
                "rate_N_per_m": k[i],
                "free_length_m": L0[i],
                "initial_tension_N": F0[i],
                "max_load_N": F_max[i],
                "max_length_m": L_max[i],
                "outer_diameter_m": D[i] + d[i],
                "wire_diameter_m": d[i],
                "material": mat.name,
                "mass_kg": mass[i],
                "price_eur": round(float(price[i]), 2),
                "rate_tolerance": RATE_TOLERANCE,
                "initial_tension_tolerance": INITIAL_TENSION_TOLERANCE,
            }
        )
    return rows, rejected


def design_rows() -> tuple[list[dict[str, object]], int]:
    """Return (accepted rows without part numbers, number of rejected candidates)."""
    rows: list[dict[str, object]] = []
    rejected = 0
    for mat, wire_mm, indices, body_coils in GRID:
        d_mm, C, Nb = np.meshgrid(
            np.asarray(wire_mm, dtype=float),
            np.asarray(indices, dtype=float),
            np.asarray(body_coils, dtype=float),
            indexing="ij",
        )
        more, bad = _rows_for(mat, d_mm.ravel() * 1e-3, C.ravel(), Nb.ravel())
        rows += more
        rejected += bad
    return rows, rejected


#: the large synthetic catalogue (benchmarks): wire diameters (mm), spring indices and
#: body coil counts drawn uniformly (log-uniform for the wire) within these ranges
LARGE_WIRE_MM = (0.3, 3.0)
LARGE_INDEX = (ph.C_MIN, ph.C_MAX)
LARGE_COILS = (4, 120)


def large_rows(parts: int, seed: int) -> tuple[list[dict[str, object]], int]:
    """``parts`` rows of random designs (both materials), deterministic for a seed."""
    rng = np.random.default_rng(seed)
    rows: list[dict[str, object]] = []
    rejected = 0
    materials = (MUSIC_WIRE, STAINLESS_302)
    while len(rows) < parts:
        n = parts - len(rows)
        which = rng.integers(0, len(materials), n)
        d = np.exp(rng.uniform(math.log(LARGE_WIRE_MM[0]), math.log(LARGE_WIRE_MM[1]), n)) * 1e-3
        C = rng.uniform(*LARGE_INDEX, n)
        Nb = rng.integers(LARGE_COILS[0], LARGE_COILS[1] + 1, n).astype(float)
        for m, mat in enumerate(materials):
            pick = which == m
            more, bad = _rows_for(mat, d[pick], C[pick], Nb[pick])
            rows += more
            rejected += bad
    return rows[:parts], rejected


def _fmt(value: object) -> str:
    if isinstance(value, str):
        return value
    return f"{float(value):.{SIG_DIGITS}g}"


def render_csv(parts: int = 0, seed: int = 0) -> tuple[str, int, int]:
    """Return (CSV text, number of items, number of rejected candidates): the shipped
    catalogue, or with ``parts`` > 0 the large synthetic one of that many parts."""
    rows, rejected = large_rows(parts, seed) if parts else design_rows()
    prefix = "CP-LRG-" if parts else "CP-EXT-"
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(COLUMNS)
    for n, row in enumerate(rows, start=1):
        row = {"part_number": f"{prefix}{n:0{5 if parts else 4}d}", **row}
        writer.writerow([_fmt(row[c]) if c != "price_eur" else f"{row[c]:.2f}" for c in COLUMNS])
    return buf.getvalue(), len(rows), rejected


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--out",
        type=Path,
        default=DEFAULT_OUT,
        help="output CSV (default: src/counterpoise/data/extension_springs.csv in the repo)",
    )
    parser.add_argument(
        "--check",
        action="store_true",
        help="do not write; exit 1 if the file at --out differs from what would be generated",
    )
    parser.add_argument("--parts", type=int, default=0, help="write a large synthetic catalogue of this many random designs instead (needs --out)")
    parser.add_argument("--seed", type=int, default=16, help="seed of the large catalogue's designs (default 16)")
    args = parser.parse_args(argv)
    if args.parts and args.out == DEFAULT_OUT:
        parser.error("--parts needs --out (the shipped catalogue is not replaced)")

    text, count, rejected = render_csv(args.parts, args.seed)

    if args.check:
        try:
            current = args.out.read_text(encoding="utf-8")
        except FileNotFoundError:
            print(f"{args.out}: missing; run scripts/make_spring_catalogue.py", file=sys.stderr)
            return 1
        if current != text:
            print(f"{args.out}: out of date; run scripts/make_spring_catalogue.py", file=sys.stderr)
            return 1
        print(f"{args.out}: up to date ({count} items)")
        return 0

    args.out.parent.mkdir(parents=True, exist_ok=True)
    tmp = args.out.with_name(args.out.name + ".tmp")
    tmp.write_text(text, encoding="utf-8", newline="")
    tmp.replace(args.out)
    print(f"generated {count} items ({rejected} rejected) -> {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
