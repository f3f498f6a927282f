"""Quantities with units: parsing, dimension checks, SI conversion and display units.

Internally every number is SI (m, kg, s, rad, N). A quantity keeps the unit it was
written in as its *display unit*, so a report shows ``0.5161 N/mm`` where the file said
``N/mm``. The pint registry is created once, on first use.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

from ..errors import UnitError

#: A string is a quantity literal when it starts with a number followed by a unit,
#: e.g. ``"135 mm"``, ``"0.5161 N/mm"``, ``"57.2deg"``; otherwise it is an expression.
_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?![\d.]|[eE][-+]?\d)"
#: (Ω, above U+00FF, is an alternative of its own: inside the character class it made
#: ``re`` build a table of the whole plane, 13 ms of every process's import.) The patterns
#: of this module are compiled on first use (``re``'s own cache), not at import: a solve
#: whose problem comes from the cache reads no quantity.
_QUANTITY = rf"^\s*{_NUMBER}(?:\s*(?:[A-Za-z°µ%]|Ω)|\s+1\s*/)"

#: Physical dimensions used by the schema, as pint dimensionality strings.
LENGTH = "[length]"
MASS = "[mass]"
DIMENSIONLESS = ""
STIFFNESS = "[mass] / [time] ** 2"
ACCELERATION = "[length] / [time] ** 2"
INVERSE_AREA = "1 / [length] ** 2"
COMPLIANCE_MASS = "[time] ** 2"  # kg per (N/m): a mass per unit of stiffness
FORCE = "[mass] * [length] / [time] ** 2"

_DIMENSION_NAMES = {
    LENGTH: "a length",
    MASS: "a mass",
    DIMENSIONLESS: "dimensionless (an angle or a ratio)",
    STIFFNESS: "a stiffness (force per length)",
    ACCELERATION: "an acceleration",
    INVERSE_AREA: "an inverse area (1/length^2)",
    COMPLIANCE_MASS: "a mass per stiffness (e.g. kg/(N/m))",
    FORCE: "a force",
}


#: Optional array libraries pint probes for when it is imported; counterpoise hands pint
#: plain floats only, and importing dask alone costs ~0.1 s (see :func:`_import_pint`).
_PINT_OPTIONAL = ("dask", "xarray", "sparse", "uncertainties", "babel", "mip", "scipy")


def _import_pint() -> Any:
    """Import pint without letting it import the array libraries it probes for (dask,
    xarray...): they stay importable afterwards, pint just does not wrap them."""
    import sys

    if "pint" in sys.modules:
        return sys.modules["pint"]
    blocked = [name for name in _PINT_OPTIONAL if name not in sys.modules]
    for name in blocked:
        sys.modules[name] = None  # type: ignore[assignment]  # import fails, find_spec returns None
    try:
        import pint
    finally:
        for name in blocked:
            if sys.modules.get(name, 0) is None:
                del sys.modules[name]
    return pint


def _cache_folder() -> Any:
    """pint's on-disk cache of the parsed definitions (``COUNTERPOISE_PINT_CACHE``: a
    folder, or ``off``); None when it cannot be used."""
    import os

    setting = os.environ.get("COUNTERPOISE_PINT_CACHE", ":auto:")
    return None if setting.lower() in ("", "off", "none", "0") else setting


@lru_cache(maxsize=1)
def ureg() -> Any:
    """The process-wide pint registry, created lazily.

    Parsing pint's definition files costs ~0.2 s per process; pint keeps the parsed result
    in a cache folder (``cache_folder=":auto:"``: the user cache directory) and then builds
    the registry in ~0.05 s. When the folder cannot be written the registry is built
    without it.
    """
    import pickle

    pint = _import_pint()
    folder = _cache_folder()
    try:
        registry = pint.UnitRegistry(autoconvert_offset_to_baseunit=True, cache_folder=folder)
    except (OSError, EOFError, pickle.UnpicklingError, ValueError, TypeError, AttributeError, ImportError):
        # an unwritable folder, or a file another process is still writing (pint writes in place)
        registry = pint.UnitRegistry(autoconvert_offset_to_baseunit=True)
    registry.formatter.default_format = "~"
    return registry


def looks_like_quantity(text: str) -> bool:
    """True when ``text`` is a quantity literal (number then unit), not an expression."""
    return bool(re.match(_QUANTITY, text))


def dimension_name(dimensionality: str) -> str:
    """Readable name of a dimensionality: 'a length', 'a stiffness (force per length)', ..."""
    canonical = {canonical_dimension(k): v for k, v in _DIMENSION_NAMES.items()}
    if dimensionality in canonical:
        return canonical[dimensionality]
    return f"a quantity of dimension {dimensionality}" if dimensionality else "dimensionless"


def dimensionality_of(q: Any) -> str:
    """Canonical dimensionality string of a pint quantity ('' when dimensionless)."""
    dim = q.dimensionality
    return "" if not dim else str(dim)


def canonical_dimension(spec: str) -> str:
    """Canonical dimensionality string for one of the module constants above."""
    if spec == DIMENSIONLESS:
        return ""
    return str(ureg().get_dimensionality(spec))


@dataclass(frozen=True)
class DisplayUnit:
    """A unit to show values in: its symbol as written and its size in SI."""

    symbol: str  # "" for dimensionless
    to_si: float  # 1 display unit = to_si SI units
    dimension: str  # canonical pint dimensionality, '' if dimensionless

    def from_si(self, value: float) -> float:
        return value / self.to_si

    @property
    def label(self) -> str:
        """Unit column text: '1' for dimensionless quantities."""
        return self.symbol or "1"


SI_DIMENSIONLESS = DisplayUnit("", 1.0, "")


#: units the reports write themselves, known without pint (a solve read from the cache
#: imports no pint: the as-built check reads its sheet's units through these)
KNOWN_UNITS = {
    "mm": DisplayUnit("mm", 1e-3, LENGTH),
    "m": DisplayUnit("m", 1.0, LENGTH),
    "deg": DisplayUnit("deg", math.pi / 180.0, DIMENSIONLESS),
    "rad": DisplayUnit("rad", 1.0, DIMENSIONLESS),
    "kg": DisplayUnit("kg", 1.0, MASS),
}


@lru_cache(maxsize=256)
def display_unit(symbol: str) -> DisplayUnit:
    """Parse a unit such as ``"N/mm"`` (empty string or ``"1"`` for dimensionless)."""
    symbol = symbol.strip()
    if symbol in ("", "1", "-"):
        return SI_DIMENSIONLESS
    if symbol in KNOWN_UNITS:
        return KNOWN_UNITS[symbol]
    reg = ureg()
    try:
        unit = reg.Quantity(1.0, symbol)
    except Exception as exc:  # pint raises several unrelated types for bad units
        raise UnitError(f"unknown unit '{symbol}'") from exc
    try:
        base = unit.to_base_units()
        to_si = float(base.magnitude)
        dimension = dimensionality_of(base)
    except Exception as exc:  # absurd powers such as 'm**9999' overflow inside pint
        raise UnitError(f"cannot use unit '{symbol}': {type(exc).__name__}") from exc
    if not (math.isfinite(to_si) and to_si > 0):
        raise UnitError(f"cannot use unit '{symbol}': its size in SI units is {to_si}")
    return DisplayUnit(symbol, to_si, dimension)


@dataclass(frozen=True)
class Quantity:
    """A parsed quantity: its SI value and the unit it was written in."""

    si: float
    unit: DisplayUnit

    @property
    def dimension(self) -> str:
        return self.unit.dimension

    @property
    def display_value(self) -> float:
        return self.unit.from_si(self.si)


_UNIT_SPLIT = rf"^\s*({_NUMBER})\s*(.*?)\s*$"


def parse_quantity(value: str | int | float) -> Quantity:
    """Parse ``"135 mm"`` or a bare number (dimensionless) into a :class:`Quantity`."""
    if isinstance(value, bool):
        raise UnitError(f"expected a quantity, got {value!r}")
    if isinstance(value, (int, float)):
        try:
            number = float(value)
        except OverflowError:  # a Python int has no size limit
            raise UnitError(f"number too large ({len(str(abs(value)))} digits)") from None
        unit = SI_DIMENSIONLESS
    else:
        match = re.match(_UNIT_SPLIT, value)
        if match is None:
            raise UnitError(f"'{value}' is not a quantity such as '135 mm'")
        number = float(match.group(1))
        unit = display_unit(match.group(2)) if match.group(2) else SI_DIMENSIONLESS
    if not math.isfinite(number):
        raise UnitError(f"value must be finite, got {value!r}")
    si = number * unit.to_si
    if not math.isfinite(si):
        raise UnitError(f"value must be finite, got {value!r} (too large once converted to SI units)")
    check_length_range(si, unit.dimension, value)
    return Quantity(si, unit)


#: largest length (m) a value may have: 1000 km. Positions, lengths and bounds beyond it are
#: typing mistakes (``1e308 mm``), and their squares (energies, residuals) overflow.
MAX_LENGTH_M = 1e6


def check_length_range(si: float, dimension: str, written: object) -> None:
    """A length of at most :data:`MAX_LENGTH_M` in size, else a :class:`UnitError`."""
    if abs(si) > MAX_LENGTH_M and dimension == canonical_dimension(LENGTH):
        raise UnitError(f"value out of range: '{written}' is {si:.3g} m; lengths up to {MAX_LENGTH_M:g} m (1000 km) are accepted")


def check_dimension(actual: str, expected: str, what: str) -> None:
    """Raise :class:`UnitError` unless dimensionality ``actual`` equals ``expected``."""
    want = canonical_dimension(expected)
    if actual != want:
        raise UnitError(f"expected {dimension_name(want)}, got {dimension_name(actual)} ({what})")


def pint_quantity(si_value: Any, unit: DisplayUnit) -> Any:
    """A pint quantity of ``si_value`` in the SI base units of ``unit`` (for dimension checks)."""
    import numpy as np

    reg = ureg()
    value = np.float64(si_value) if isinstance(si_value, (int, float)) else si_value  # 1/0 -> inf, not an exception
    if not unit.symbol:
        return reg.Quantity(value, "")
    return reg.Quantity(value, _base_units(unit.symbol))


@lru_cache(maxsize=256)
def _base_units(symbol: str) -> Any:
    return ureg().Quantity(1.0, symbol).to_base_units().units


def base_unit_symbol(q: Any) -> str:
    """Short SI symbol of a pint quantity's base units ('' when dimensionless)."""
    base = q.to_base_units()
    return "" if base.dimensionless else f"{base.units:~}"


@lru_cache(maxsize=256)
def is_angle_unit(symbol: str) -> bool:
    """True for a unit of angle ('deg', 'rad', '°', 'arcmin', 'turn'); False for '' and
    for other dimensionless units such as '%' (pint treats both as dimensionless)."""
    if not symbol.strip():
        return False
    try:
        base = ureg().Quantity(1.0, symbol).to_base_units()
    except Exception:  # not a unit at all: not an angle either
        return False
    return bool(base.dimensionless) and base.units == ureg().radian


#: Largest bare number read as radians first in a hint (2π: a full turn); larger ones are
#: most likely degrees.
RADIAN_HINT_LIMIT = 2 * math.pi


def angle_hint(number: float) -> str:
    """How to write a bare number meant as an angle: "write '90 deg' or '1.5708 rad'"."""
    deg = f"'{number:g} deg' or '{math.radians(number):.5g} rad'"
    rad = f"'{number:g} rad' or '{math.degrees(number):.5g} deg'"
    return f"write {rad if abs(number) <= RADIAN_HINT_LIMIT and not float(number).is_integer() else deg}"
