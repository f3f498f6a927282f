"""Spring materials and the standard wire-diameter series (read once from ``counterpoise/data``).

``spring_materials.csv``: one row per material, the constants of Shigley's Mechanical
Engineering Design (9th ed.), ch. 10: shear and Young's moduli (table 10-5), the tensile
strength fit ``Sut = A / d^m`` with d in mm and its diameter range (table 10-4), and the
allowable stresses of a statically loaded extension spring as fractions of Sut (table 10-7:
body torsion, end torsion, end bending). ``spring_wire_diameters.csv``: a preferred
metric series of wire diameters; a material uses the part of it inside its Sut range.
See docs/springs.md.
"""

from __future__ import annotations

import csv
import functools
from dataclasses import dataclass
from pathlib import Path

#: the material a designed spring is made of unless the problem file says otherwise
DEFAULT_MATERIAL = "music_wire"


@dataclass(frozen=True)
class Material:
    key: str  # what a problem file writes: ``material = "music_wire"``
    name: str  # what reports write
    G: float  # shear modulus, Pa
    E: float  # Young's modulus, Pa
    A: float  # Sut = A / d^m: MPa·mm^m
    m: float
    d_min: float  # range of the Sut fit, m
    d_max: float
    body_torsion: float  # allowable body shear stress / Sut
    end_torsion: float  # allowable hook torsion stress / Sut
    end_bending: float  # allowable hook bending stress / Sut
    density: float  # kg/m³


#: the package's data folder (beside the package's modules in every install the project
#: supports; read by path: ``importlib.resources`` and the zip readers it loads cost ~6 ms
#: of a single solve)
DATA = Path(__file__).resolve().parent.parent / "data"


def _data(name: str) -> list[dict[str, str]]:
    text = (DATA / name).read_text(encoding="utf-8")
    return list(csv.DictReader(text.splitlines()))


@functools.lru_cache(maxsize=1)
def materials() -> dict[str, Material]:
    """Every material of the table, by key."""
    out = {}
    for r in _data("spring_materials.csv"):
        out[r["key"]] = Material(
            key=r["key"],
            name=r["name"],
            G=float(r["G_Pa"]),
            E=float(r["E_Pa"]),
            A=float(r["A_MPa_mm_m"]),
            m=float(r["m"]),
            d_min=float(r["d_min_mm"]) * 1e-3,
            d_max=float(r["d_max_mm"]) * 1e-3,
            body_torsion=float(r["body_torsion"]),
            end_torsion=float(r["end_torsion"]),
            end_bending=float(r["end_bending"]),
            density=float(r["density_kg_m3"]),
        )
    return out


def material(key: "str | Material") -> Material:
    """The material of this key (or the material itself); an unknown key is a ``KeyError``
    whose message lists the known ones (the loader turns it into an input error)."""
    if isinstance(key, Material):
        return key
    table = materials()
    if key not in table:
        raise KeyError(f"unknown spring material '{key}' (known: {', '.join(table)})")
    return table[key]


@functools.lru_cache(maxsize=1)
def wire_series() -> tuple[float, ...]:
    """The standard wire diameters (m), ascending."""
    return tuple(sorted(float(r["wire_diameter_mm"]) * 1e-3 for r in _data("spring_wire_diameters.csv")))


def wire_diameters(mat: "str | Material") -> tuple[float, ...]:
    """The standard wire diameters (m) inside the material's Sut range."""
    m = material(mat)
    return tuple(d for d in wire_series() if m.d_min * (1 - 1e-9) <= d <= m.d_max * (1 + 1e-9))
