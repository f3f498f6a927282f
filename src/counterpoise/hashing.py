"""BLAKE2b for the cache keys and the problem's content key, without loading OpenSSL.

``hashlib.blake2b`` is CPython's own ``_blake2`` module; importing :mod:`hashlib` also loads
OpenSSL's library (~4 ms of a repeated ``counterpoise solve``). The same function, the same
digests; :mod:`hashlib`'s where a Python has no ``_blake2``.
"""

from __future__ import annotations

try:
    from _blake2 import blake2b
except ImportError:  # pragma: no cover - a Python without it
    from hashlib import blake2b

__all__ = ["blake2b"]
