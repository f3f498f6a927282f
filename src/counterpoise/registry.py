"""The registry of design layers: the one list of the layers that extend the core designer.

A design layer is a package that wraps the core design method when a problem needs it (a
payload range, a robust counterpart, catalogue parts, the springs' realisation) and reports
what it found. Each is one :class:`Entry` here, innermost first: the order in which
:func:`counterpoise.pipeline.build_method` wraps them (so the outermost, the realisation
layer, is last) and in which the reports take their lines and files. The entry names the
module whose ``LAYER`` (a :class:`counterpoise.designer.layers.Layer`) does the work; it is
imported only when a layer is used (:func:`counterpoise.designer.layers.layers`), so this
module imports nothing and any layer may read it: its verdict source
(:data:`counterpoise.designer.solution.VERDICT_SOURCES`) and the problem-file tables it
cannot be combined with yet (checked when a file is read, :mod:`counterpoise.io.resolve`).

Adding a layer: its package (with its ``LAYER``) and one line below.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Entry:
    """One design layer: ``name`` is its verdict source; ``module`` defines its ``LAYER``."""

    name: str
    module: str
    #: the problem-file table that asks for the layer ("" when none does)
    table: str = ""
    #: problem-file tables the layer's table cannot be combined with yet, and where the docs say why
    not_with: tuple[str, ...] = ()
    docs: str = ""


#: the design layers, innermost first
REGISTRY: tuple[Entry, ...] = (
    Entry("payload", "counterpoise.payload.layer", table="payloads"),
    Entry("robust", "counterpoise.robust.layer", table="robust"),
    Entry("parts", "counterpoise.selection.layer", table="slots"),
    Entry("realisation", "counterpoise.realisation.layer"),
)


def names() -> tuple[str, ...]:
    """The registered layers' names (their verdict sources), innermost first."""
    return tuple(entry.name for entry in REGISTRY)
