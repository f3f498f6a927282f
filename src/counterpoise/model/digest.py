"""A stable digest of a resolved problem's content: the key of every cache of built designers.

:func:`content_key` walks the problem's dataclass *fields* (not cached properties), so two
problems get one key exactly when every value that goes into a design is the same: a
``--set`` override, an edited problem or a second study on a long-lived Dask cluster give
another key, and a problem loaded twice from the same text gives the same key in every
process (the digest uses no ``hash()``, whose value for strings changes between processes).

Floats are written with ``repr`` (exact: it round-trips), mappings in sorted key order,
sets sorted, numpy arrays by dtype, shape and bytes. The key of a problem is computed once
and kept on the object (problems are frozen).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np

from ..hashing import blake2b

#: attribute under which a problem keeps its key (not a dataclass field: repr, eq and
#: dataclasses.replace ignore it)
_ATTRIBUTE = "_content_key"
_PRIMITIVES = (str, int, float, bool, type(None))


def _feed(h: Any, obj: Any, skip: frozenset[str] = frozenset()) -> None:
    kind = type(obj)
    if kind in _PRIMITIVES:
        h.update(f"{kind.__name__}:{obj!r};".encode())
    elif dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        h.update(f"<{kind.__module__}.{kind.__qualname__}".encode())
        for f in dataclasses.fields(obj):
            if f.name in skip:
                continue
            h.update(f"|{f.name}=".encode())
            _feed(h, getattr(obj, f.name), skip)
        h.update(b">")
    elif isinstance(obj, (tuple, list)):
        h.update(f"[{len(obj)}:".encode())
        if all(type(x) in _PRIMITIVES for x in obj):  # fast path: long catalogue columns
            h.update(repr(tuple(obj)).encode())
        else:
            for x in obj:
                _feed(h, x, skip)
        h.update(b"]")
    elif isinstance(obj, Mapping):
        items = sorted(obj.items(), key=lambda kv: repr(kv[0]))
        h.update(f"{{{len(items)}:".encode())
        for k, v in items:
            _feed(h, k, skip)
            _feed(h, v, skip)
        h.update(b"}")
    elif isinstance(obj, (set, frozenset)):
        _feed(h, sorted(obj, key=repr), skip)
    elif isinstance(obj, np.ndarray):
        h.update(f"nd:{obj.dtype.str}:{obj.shape}:".encode())
        h.update(np.ascontiguousarray(obj).tobytes())
    elif isinstance(obj, np.generic):
        _feed(h, obj.item())
    else:  # an enum or another plain value: its repr is its content
        h.update(f"{kind.__qualname__}:{obj!r};".encode())


def digest(obj: Any, skip: frozenset[str] = frozenset()) -> str:
    """Hex digest (BLAKE2b, 16 bytes) of ``obj``'s content (see the module's rules);
    dataclass fields named in ``skip`` are left out."""
    h = blake2b(digest_size=16)
    _feed(h, obj, skip)
    return h.hexdigest()


#: the fields that say where a problem's files lie, not what they hold
LOCATIONS = frozenset({"path"})


def content_key_anywhere(problem: Any) -> str:
    """The content key of a problem wherever its files lie: :func:`content_key` without the
    paths of the problem file and its catalogues (:data:`LOCATIONS`), so that the same
    file read by another relative path, from another folder, gives the same key. A study
    records it (``study.json``) and ``--resume`` continues only a study of an equal key."""
    return digest(problem, LOCATIONS)


def content_key(problem: Any) -> str:
    """The content key of a resolved problem: equal for equal content, different as soon as
    any field differs (a parameter, a bound, a setting, a catalogue row, the name or path)."""
    key = problem.__dict__.get(_ATTRIBUTE) if hasattr(problem, "__dict__") else None
    if key is None:
        key = digest(problem)
        if hasattr(problem, "__dict__"):
            problem.__dict__[_ATTRIBUTE] = key  # frozen: bypass __setattr__, like cached_property
    return key
