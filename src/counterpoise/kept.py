"""A few built things kept by key, the least recently used dropped first.

What a worker builds once and reuses across calls (design methods, part-search models,
payload adjusters) is kept here under a key of the problem's content
(:func:`counterpoise.model.digest.content_key`), never its name or path.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable, Hashable
from typing import Generic, TypeVar

K = TypeVar("K", bound=Hashable)
V = TypeVar("V")


class Kept(Generic[K, V]):
    """At most ``size`` values by key, each built on first use."""

    def __init__(self, size: int) -> None:
        if size < 1:
            raise ValueError("a cache keeps at least one value")
        self.size = size
        self._values: OrderedDict[K, V] = OrderedDict()

    def get(self, key: K, build: Callable[[], V]) -> V:
        """The value kept under ``key``, or ``build()`` kept under it (the least recently
        used value dropped beyond :attr:`size`)."""
        if key in self._values:
            self._values.move_to_end(key)
            return self._values[key]
        value = build()
        self._values[key] = value
        while len(self._values) > self.size:
            self._values.popitem(last=False)
        return value

    def __len__(self) -> int:
        return len(self._values)
