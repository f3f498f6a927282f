"""Bought parts: spring catalogues, spring slots and how the designer chooses among them.

A :class:`Catalogue` is a table of extension springs read from a CSV file
(:mod:`counterpoise.catalogue` reads and validates it). A :class:`SpringSlot` is a place in
the design that takes one part of a catalogue; several springs may share a slot ("the same
part for all legs"). The slot's name stands for the chosen part's rate: the loader adds it
as a literal parameter (value: a representative rate of the catalogue) and every spring of
the slot uses it as its stiffness, so the designer re-solves a candidate part by passing
its rate as a parameter, without rebuilding anything.

How a part realises a zero-free-length spring (F = k·d between the two attachment points,
through a string over a pulley) and the limits that follow are in
:mod:`counterpoise.catalogue.limits`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any, SupportsInt
from collections.abc import Iterable

import numpy as np

#: The numeric columns of a catalogue, SI. ``mass``, ``price`` and the tolerances may be NaN (unknown).
NUMERIC_FIELDS = (
    "rate",
    "free_length",
    "initial_tension",
    "max_load",
    "max_length",
    "outer_diameter",
    "wire_diameter",
    "mass",
    "price",
    "rate_tolerance",
    "initial_tension_tolerance",
)


@dataclass(frozen=True)
class Catalogue:
    """A validated table of extension springs, SI units; one entry per part in every tuple."""

    name: str
    path: str
    part_number: tuple[str, ...]
    material: tuple[str, ...]
    rate: tuple[float, ...]  # N/m
    free_length: tuple[float, ...]  # m, L0
    initial_tension: tuple[float, ...]  # N, F0
    max_load: tuple[float, ...]  # N
    max_length: tuple[float, ...]  # m
    outer_diameter: tuple[float, ...]  # m (NaN if unknown)
    wire_diameter: tuple[float, ...]  # m (NaN if unknown)
    mass: tuple[float, ...]  # kg (NaN if unknown)
    price: tuple[float, ...]  # in the catalogue's currency (NaN if unknown)
    rate_tolerance: tuple[float, ...]  # fraction, ± (NaN if unknown)
    initial_tension_tolerance: tuple[float, ...]  # fraction, ± (NaN if unknown)
    currency: str = ""
    #: slots with ``count``: how many identical springs of the base part work in parallel
    #: (empty: one each) and the base part's number (empty: ``part_number``)
    count: tuple[int, ...] = ()
    base_part: tuple[str, ...] = ()

    def parts_in_parallel(self, row: int) -> int:
        return self.count[row] if self.count else 1

    def base_part_number(self, row: int) -> str:
        return self.base_part[row] if self.base_part else self.part_number[row]

    def parallel(self, lowest: int, highest: int) -> "Catalogue":
        """Every part as ``n`` identical springs in parallel behind one cable, for n from
        ``lowest`` to ``highest``: rate, initial tension, largest load, mass and price n times
        the part's; lengths, diameters and tolerances (fractions) the part's. A part of n > 1
        is numbered ``<part> x<n>``. The part search then enumerates the counts with the parts."""
        counts = range(lowest, highest + 1)
        idx = [(i, n) for n in counts for i in range(len(self))]
        scaled = {"rate", "initial_tension", "max_load", "mass", "price"}
        pick: dict[str, Any] = {n: tuple(getattr(self, n)[i] * (k if n in scaled else 1) for i, k in idx) for n in NUMERIC_FIELDS}
        pick["material"] = tuple(self.material[i] for i, _ in idx)
        pick["part_number"] = tuple(self.part_number[i] if k == 1 else f"{self.part_number[i]} x{k}" for i, k in idx)
        return Catalogue(
            self.name, self.path, currency=self.currency, count=tuple(k for _, k in idx), base_part=tuple(self.base_part_number(i) for i, _ in idx), **pick
        )

    def __len__(self) -> int:
        return len(self.part_number)

    def array(self, name: str) -> np.ndarray:
        """A numeric column as a float array."""
        return np.asarray(getattr(self, name), dtype=float)

    @cached_property
    def arrays(self) -> dict[str, np.ndarray]:
        return {n: self.array(n) for n in NUMERIC_FIELDS}

    def subset(self, rows: Iterable[SupportsInt]) -> "Catalogue":
        """The catalogue restricted to ``rows`` (indices), in that order."""
        idx = [int(i) for i in rows]
        pick = {n: tuple(getattr(self, n)[i] for i in idx) for n in ("part_number", "material", *NUMERIC_FIELDS)}
        extra = {n: tuple(getattr(self, n)[i] for i in idx) for n in ("count", "base_part") if getattr(self, n)}
        return Catalogue(self.name, self.path, currency=self.currency, **pick, **extra)


@dataclass(frozen=True)
class SpringSlot:
    """A place for one catalogue part, shared by ``springs``; its name is its rate's symbol."""

    name: str
    catalogue: Catalogue
    springs: tuple[str, ...]
    rate_tolerance: float  # fraction used by the tolerance report
    initial_tension_tolerance: float
    description: str = ""


#: What the choice of parts minimises first (the others break ties, in this order).
PREFERENCES = ("objective", "robust", "price")


@dataclass(frozen=True)
class SelectionSettings:
    """How parts are chosen (``[selection]`` in a problem file)."""

    prefer: str = "objective"
    #: variables re-solved per tolerance corner (an adjustment screw); empty: no re-adjustment
    adjust: tuple[str, ...] = ()
    #: exhaustive enumeration when the product of candidate counts of interacting slots is at most this
    max_enumeration: int = 400
    #: configurations per (subsystem, scenario) for the limit checks of candidates
    limit_samples: int = 512
    nearest: int = 5  # nearest candidates reported when no part fits
