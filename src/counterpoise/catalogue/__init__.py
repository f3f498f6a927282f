"""Spring catalogues: the CSV schema, column mappings for vendor tables, row validation,
and the limits a catalogue part puts on a zero-free-length spring it realises.

This layer sits between :mod:`counterpoise.model` and :mod:`counterpoise.io`: the loader
reads the catalogues a problem file names through it. Nothing here solves anything.

- :mod:`.columns`: the schema (canonical fields, units) and the column mappings;
- :mod:`.reader`: :func:`read_catalogue`, with file/row/column errors;
- :mod:`.limits`: the realisability limits of a part, vectorised over parts and configurations.
"""

from __future__ import annotations

from .columns import FIELDS, PRESETS, UNIT_SYSTEMS, ColumnMapping, mapping_from
from .reader import SHIPPED, CatalogueError, read_catalogue, shipped_catalogue_path

__all__ = [
    "FIELDS",
    "PRESETS",
    "SHIPPED",
    "UNIT_SYSTEMS",
    "CatalogueError",
    "ColumnMapping",
    "mapping_from",
    "read_catalogue",
    "shipped_catalogue_path",
]
