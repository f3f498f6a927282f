"""The catalogue schema and the column mappings that read vendor tables onto it.

Canonical fields (see ``docs/catalogues.md``):

=========================== ========== ======== ==========================================
field                       SI unit    required meaning
=========================== ========== ======== ==========================================
part_number                 –          yes      unique part number
rate                        N/m        yes      k, slope of force against extension
free_length                 m          yes      L0, inside the hooks, unloaded
initial_tension             N          yes      F0, force before the coils separate
max_load                    N          yes      largest allowed force
max_length                  m          yes      largest allowed length (inside the hooks)
outer_diameter              m          no       coil outer diameter
wire_diameter               m          no       wire diameter
material                    –          no       text
mass                        kg         no       mass of one spring
price                       currency   no       price of one package (see package_quantity)
package_quantity            –          no       springs per package (price per spring = price / quantity)
rate_tolerance              fraction   no       ± relative tolerance of the rate (0.10 = ±10 %)
initial_tension_tolerance   fraction   no       ± relative tolerance of the initial tension
=========================== ========== ======== ==========================================

A :class:`ColumnMapping` says which CSV column holds each field and in which unit system
the numbers are written. Three presets: ``counterpoise`` (the shipped catalogue: SI with
the unit in the column name), ``vendor`` (columns
``stiffness,length_natural,length_max,load_min,load_max,od,wire_dia,part_number`` and
``material,pkg_qty,pkg_cost``; ``load_min`` is the initial tension) in SI, and
``vendor_inch``, the same columns in inch, lbf/in and lbf.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

#: field -> kind of quantity ('' for text, 'count', 'fraction', 'money').
FIELDS: dict[str, str] = {
    "part_number": "",
    "rate": "stiffness",
    "free_length": "length",
    "initial_tension": "force",
    "max_load": "force",
    "max_length": "length",
    "outer_diameter": "length",
    "wire_diameter": "length",
    "material": "",
    "mass": "mass",
    "price": "money",
    "package_quantity": "count",
    "rate_tolerance": "fraction",
    "initial_tension_tolerance": "fraction",
}
REQUIRED = ("part_number", "rate", "free_length", "initial_tension", "max_load", "max_length")

#: unit system -> factor to SI for each kind of quantity, and the unit's name for messages.
UNIT_SYSTEMS: dict[str, dict[str, tuple[float, str]]] = {
    "SI": {"stiffness": (1.0, "N/m"), "length": (1.0, "m"), "force": (1.0, "N"), "mass": (1.0, "kg")},
    "N-mm": {"stiffness": (1e3, "N/mm"), "length": (1e-3, "mm"), "force": (1.0, "N"), "mass": (1e-3, "g")},
    "inch": {
        "stiffness": (4.4482216152605 / 0.0254, "lbf/in"),
        "length": (0.0254, "in"),
        "force": (4.4482216152605, "lbf"),
        "mass": (0.45359237, "lb"),
    },
}

#: Where the median of a column must lie for a catalogue of extension springs (SI units).
#: Stock extension springs run from watch-size (0.1 N/mm, 3 mm long, 0.1 mm wire) to
#: garage-door size (a few hundred N/mm, under a metre free, 15 mm wire). The bands are a
#: decade or more wider than that: they catch a whole file read in the wrong units
#: (lengths in mm read as m are 1000 times too large), not an unusual part.
PLAUSIBLE: dict[str, tuple[float, float]] = {
    "rate": (1.0, 1e6),  # N/m: 1 N/m to 1000 N/mm
    "free_length": (1e-3, 1.0),  # m: 1 mm to 1 m
    "max_length": (1e-3, 3.0),  # m
    "max_load": (1e-2, 1e5),  # N
    "outer_diameter": (5e-4, 0.3),  # m
    "wire_diameter": (5e-5, 0.03),  # m
    "mass": (1e-7, 50.0),  # kg
}
#: A typical median of each column (the shipped catalogue's, rounded): where several unit
#: systems make a file plausible, the one closest to these (in log scale) is suggested.
TYPICAL: dict[str, float] = {
    "rate": 1e3,
    "free_length": 0.04,
    "max_length": 0.08,
    "max_load": 50.0,
    "outer_diameter": 0.01,
    "wire_diameter": 1e-3,
    "mass": 5e-3,
}
#: Ratios of the required columns that are plausible whatever the file lacks (no diameters,
#: no mass): each is a force per area, set by the wire's strength and modulus, so a whole
#: file in other units moves it by the ratio of their force and squared length units (an
#: inch/lbf file read as N-mm: 145 times). Field -> (numerator, denominator, power of the
#: denominator), band (SI, N/m²) and typical median. The shipped catalogue's medians are
#: 0.025 N/mm² (load / free length²) and 0.027 N/mm² (rate / free length), its extremes
#: 0.0005 and 0.85 N/mm²; the bands are a decade and more beyond them, and below the
#: physical limits (a helical spring of index ≥ 4 and ≥ 3 coils in 1000 MPa steel stays
#: under ~11 N/mm² in load / free length², under ~17 N/mm² in rate / free length).
DERIVED: dict[str, tuple[str, str, int]] = {
    "rate_per_length": ("rate", "free_length", 1),
    "load_per_area": ("max_load", "free_length", 2),
}
DERIVED_PLAUSIBLE: dict[str, tuple[float, float]] = {
    "rate_per_length": (50.0, 3e6),  # N/m²: 5e-5 to 3 N/mm per mm (N/mm²)
    "load_per_area": (100.0, 3e6),  # N/m²: 1e-4 to 3 N/mm²
}
DERIVED_TYPICAL: dict[str, float] = {"rate_per_length": 2.7e4, "load_per_area": 2.5e4}
DERIVED_TEXT: dict[str, tuple[str, str]] = {  # (what, band)
    "rate_per_length": ("rate / free length", "5e-05 to 3 N/mm²"),
    "load_per_area": ("max load / free length²", "1e-04 to 3 N/mm²"),
}

#: How a band is written in a message.
PLAUSIBLE_TEXT: dict[str, str] = {
    "rate": "1 N/m to 1000 N/mm",
    "free_length": "1 mm to 1 m",
    "max_length": "1 mm to 3 m",
    "max_load": "0.01 N to 100 kN",
    "outer_diameter": "0.5 mm to 300 mm",
    "wire_diameter": "0.05 mm to 30 mm",
    "mass": "0.1 mg to 50 kg",
}

_VENDOR = {
    "part_number": "part_number",
    "rate": "stiffness",
    "free_length": "length_natural",
    "initial_tension": "load_min",
    "max_load": "load_max",
    "max_length": "length_max",
    "outer_diameter": "od",
    "wire_diameter": "wire_dia",
    "material": "material",
    "price": "pkg_cost",
    "package_quantity": "pkg_qty",
}


@dataclass(frozen=True)
class ColumnMapping:
    """Which column holds each field (``columns``: field -> column name) and the unit system."""

    columns: tuple[tuple[str, str], ...]
    units: str = "SI"
    #: fields whose column may be missing from the file (then unknown, NaN)
    optional_columns: tuple[str, ...] = ()

    @property
    def column(self) -> dict[str, str]:
        return dict(self.columns)

    def factor(self, field: str) -> float:
        kind = FIELDS[field]
        return UNIT_SYSTEMS[self.units][kind][0] if kind in UNIT_SYSTEMS[self.units] else 1.0

    def unit_name(self, field: str) -> str:
        kind = FIELDS[field]
        if kind in UNIT_SYSTEMS[self.units]:
            return UNIT_SYSTEMS[self.units][kind][1]
        return {"fraction": "fraction", "money": "currency", "count": "count"}.get(kind, "")


PRESETS: dict[str, ColumnMapping] = {
    "counterpoise": ColumnMapping(
        (
            ("part_number", "part_number"),
            ("rate", "rate_N_per_m"),
            ("free_length", "free_length_m"),
            ("initial_tension", "initial_tension_N"),
            ("max_load", "max_load_N"),
            ("max_length", "max_length_m"),
            ("outer_diameter", "outer_diameter_m"),
            ("wire_diameter", "wire_diameter_m"),
            ("material", "material"),
            ("mass", "mass_kg"),
            ("price", "price_eur"),
            ("rate_tolerance", "rate_tolerance"),
            ("initial_tension_tolerance", "initial_tension_tolerance"),
        ),
        "SI",
        optional_columns=("mass", "price", "rate_tolerance", "initial_tension_tolerance"),
    ),
    "vendor": ColumnMapping(tuple(_VENDOR.items()), "SI", optional_columns=("material", "price", "package_quantity")),
    "vendor_inch": ColumnMapping(tuple(_VENDOR.items()), "inch", optional_columns=("material", "price", "package_quantity")),
}


def mapping_from(columns: str | Mapping[str, str] | None, units: str | None = None) -> ColumnMapping:
    """A mapping from a preset name or a field -> column table (``units`` overrides the system).

    Raises ``ValueError`` with a one-line message for an unknown preset, field or unit system.
    """
    if units is not None and units not in UNIT_SYSTEMS:
        raise ValueError(f"unknown unit system '{units}': use one of {', '.join(UNIT_SYSTEMS)}")
    if columns is None or isinstance(columns, str):
        name = columns or "counterpoise"
        if name not in PRESETS:
            raise ValueError(f"unknown column preset '{name}': use one of {', '.join(PRESETS)} or a table field = column")
        preset = PRESETS[name]
        return ColumnMapping(preset.columns, units or preset.units, preset.optional_columns)
    unknown = sorted(set(columns) - set(FIELDS))
    if unknown:
        raise ValueError(f"unknown catalogue field '{unknown[0]}': fields are {', '.join(FIELDS)}")
    missing = [f for f in REQUIRED if f not in columns]
    if missing:
        raise ValueError(f"the column mapping must name a column for {', '.join(missing)}")
    return ColumnMapping(tuple((f, str(c)) for f, c in columns.items()), units or "SI")
