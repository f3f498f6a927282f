"""Spring materials and the standard wire-diameter series (read once from ``counterpoise/data``).

``spring_materials.csv``: one row per material, the constants of Shigley's Mechanical
Engineering Design (9th ed.), ch. 10: the tensile strength fit ``Sut = A / d^m`` with d in
mm and its diameter range (table 10-4), and the allowable stresses of a statically loaded
extension spring as fractions of Sut (table 10-7: body torsion, end torsion, end bending).
``spring_moduli.csv``: the shear and Young's moduli by material and wire size (table 10-5:
music wire has four diameter bands, the other materials one value). ``spring_wire_diameters.csv``:
a preferred metric series of wire diameters; a material uses the part of it inside its Sut
range. See docs/springs.md.
"""

from __future__ import annotations

import csv
import functools
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

#: the material a designed spring is made of unless the problem file says otherwise
DEFAULT_MATERIAL = "music_wire"
#: one inch (m): table 10-5 gives its diameter bands in inches
INCH = 0.0254
#: table 10-5 quotes diameters to 0.001 in: a wire is in the band of its diameter so rounded
#: (its bands "< 0.032", "0.033-0.063", ... leave no size out at that resolution)
BAND_RESOLUTION = 0.001 * INCH


@dataclass(frozen=True)
class Moduli:
    """Shear and Young's moduli (Pa) of a material's wire up to a diameter (m; inf: every
    larger size), a row of ``spring_moduli.csv``."""

    d_max: float
    G: float
    E: float


@dataclass(frozen=True)
class Material:
    key: str  # what a problem file writes: ``material = "music_wire"``
    name: str  # what reports write
    moduli: tuple[Moduli, ...]  # by wire size, ascending d_max (table 10-5)
    A: float  # Sut = A / d^m: MPa·mm^m
    m: float
    d_min: float  # range of the Sut fit, m
    d_max: float
    body_torsion: float  # allowable body shear stress / Sut
    end_torsion: float  # allowable hook torsion stress / Sut
    end_bending: float  # allowable hook bending stress / Sut
    density: float  # kg/m³

    def _band(self, d: Any) -> Any:
        """The index into ``moduli`` of wire diameter(s) ``d`` (m), the diameter rounded
        to :data:`BAND_RESOLUTION` as table 10-5 quotes it."""
        limits = np.array([m.d_max for m in self.moduli[:-1]], dtype=float)
        rounded = np.round(np.asarray(d, dtype=float) / BAND_RESOLUTION) * BAND_RESOLUTION
        return np.searchsorted(limits * (1 + 1e-9), rounded, side="left")

    def shear_modulus(self, d: Any) -> Any:
        """G (Pa) of wire of diameter(s) ``d`` (m): a float for a float, else an array."""
        G = np.array([m.G for m in self.moduli])[self._band(d)]
        return float(G) if np.ndim(G) == 0 else G

    def youngs_modulus(self, d: Any) -> Any:
        """E (Pa) of wire of diameter(s) ``d`` (m): a float for a float, else an array."""
        E = np.array([m.E for m in self.moduli])[self._band(d)]
        return float(E) if np.ndim(E) == 0 else E


#: the package's data folder (beside the package's modules in every install the project
#: supports; read by path: ``importlib.resources`` and the zip readers it loads cost ~6 ms
#: of a single solve)
DATA = Path(__file__).resolve().parent.parent / "data"


def _data(name: str) -> list[dict[str, str]]:
    text = (DATA / name).read_text(encoding="utf-8")
    return list(csv.DictReader(text.splitlines()))


def _moduli() -> dict[str, tuple[Moduli, ...]]:
    """The rows of ``spring_moduli.csv`` by material, ascending wire size; a blank
    ``d_max_in`` is the band of every larger size (the last one)."""
    out: dict[str, list[Moduli]] = {}
    for r in _data("spring_moduli.csv"):
        d_max = float(r["d_max_in"]) * INCH if r["d_max_in"].strip() else math.inf
        out.setdefault(r["material"], []).append(Moduli(d_max, float(r["G_Pa"]), float(r["E_Pa"])))
    return {key: tuple(sorted(rows, key=lambda m: m.d_max)) for key, rows in out.items()}


@functools.lru_cache(maxsize=1)
def materials() -> dict[str, Material]:
    """Every material of the table, by key."""
    out = {}
    moduli = _moduli()
    for r in _data("spring_materials.csv"):
        out[r["key"]] = Material(
            key=r["key"],
            name=r["name"],
            moduli=moduli[r["key"]],
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
