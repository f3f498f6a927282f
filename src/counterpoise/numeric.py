"""A CasADi function evaluated on numpy arrays through its own buffers.

Calling a ``casadi.Function`` from Python converts every numpy argument to a ``DM`` and
every ``DM`` result back (``np.array(dm)`` goes through a Python list of its elements):
for the small functions a study point evaluates (the balance equalities and their
Jacobian, the LP's coefficients, the objective) that conversion costs several times the
evaluation itself (≈ 0.4 ms against ≈ 0.04 ms for a 6 × 6 Jacobian). CasADi's
``Function.buffer()`` evaluates the same compiled function on memory given once (numpy
arrays here), with no conversion: the same arithmetic, so the same numbers, bit for bit
(``tests/test_numeric_function.py``).

A buffer holds the function's work memory, so each thread gets its own (a CasADi function
is not safe to call from two threads at once; a Dask worker may run several task threads).
A solver (IPOPT's ``nlpsol``) is evaluated the same way; its statistics (return status,
iterations) are then those of the buffer's memory: :meth:`NumericFunction.stats`.
"""

from __future__ import annotations

import threading
from typing import Any

import numpy as np


class NumericFunction:
    """``f(*args)`` -> the dense outputs of the CasADi ``function`` as 2-D row-major float
    arrays, as ``np.array(dm)`` gives them (the memory order matters: numpy's products of a
    column-major matrix round differently), from numpy (or scalar) arguments of its input sizes.

    Inputs with a sparse pattern, or a CasADi without ``Function.buffer``, go through the
    ordinary call (same results, slower).

    ``remember``: the outputs of that many latest distinct inputs (first in, first out) are kept (per thread) and
    given again (as copies) for the same inputs, bit for bit: a polish evaluates the
    balance equalities at a point it reached a moment before."""

    def __init__(self, function: Any, remember: int = 0) -> None:
        self.function = function
        self.remember = remember
        n_in, n_out = int(function.n_in()), int(function.n_out())
        self._in_sizes = [int(function.sparsity_in(i).numel()) for i in range(n_in)]
        dense_in = all(function.sparsity_in(i).is_dense() for i in range(n_in))
        self._out_shapes: list[tuple[int, int]] = []
        self._out_index: list[np.ndarray | None] = []  # column-major positions of the nonzeros (None: dense)
        self._out_nnz: list[int] = []
        for i in range(n_out):
            sp = function.sparsity_out(i)
            self._out_shapes.append((int(sp.size1()), int(sp.size2())))
            self._out_nnz.append(int(sp.nnz()))
            if sp.is_dense():
                self._out_index.append(None)
            else:
                rows, cols = sp.get_triplet()
                self._out_index.append(np.asarray(rows, dtype=np.intp) + np.asarray(cols, dtype=np.intp) * int(sp.size1()))
        self._fast = dense_in and hasattr(function, "buffer")
        self._local = threading.local()

    def _buffers(self) -> tuple[Any, list[np.ndarray], list[np.ndarray]]:
        found = getattr(self._local, "buffers", None)
        if found is None:
            buffer, evaluate = self.function.buffer()
            inputs = [np.zeros(n) for n in self._in_sizes]
            outputs = [np.zeros(n) for n in self._out_nnz]
            for i, a in enumerate(inputs):
                buffer.set_arg(i, a.data)  # a memoryview of the array
            for i, r in enumerate(outputs):
                buffer.set_res(i, r.data)
            found = self._local.buffers = (evaluate, inputs, outputs, buffer)
        return found[0], found[1], found[2]

    def __call__(self, *args: Any) -> tuple[np.ndarray, ...]:
        values = [np.asarray(a, dtype=float).reshape(-1, order="F") for a in args] if self._fast else []
        if not self._fast or len(values) != len(self._in_sizes) or any(v.size != n for v, n in zip(values, self._in_sizes)):
            self._local.buffered = False
            return tuple(np.array(v, dtype=float) for v in self.function.call(list(args)))  # the ordinary call (and its errors)
        self._local.buffered = True
        if self.remember:
            key = b"".join(v.tobytes() for v in values)
            kept: dict[bytes, tuple[np.ndarray, ...]] = self._local.__dict__.setdefault("kept", {})
            found = kept.get(key)
            if found is None:
                found = kept[key] = self._evaluate(values)
                while len(kept) > self.remember:
                    del kept[next(iter(kept))]
            return tuple(a.copy() for a in found)
        return self._evaluate(values)

    def _evaluate(self, values: list[np.ndarray]) -> tuple[np.ndarray, ...]:
        evaluate, inputs, outputs = self._buffers()
        for target, value in zip(inputs, values):
            target[:] = value
        evaluate()
        out = []
        for r, shape, index in zip(outputs, self._out_shapes, self._out_index):
            if index is None:
                out.append(r.reshape(shape, order="F").copy())
            else:
                dense = np.zeros(shape[0] * shape[1])
                dense[index] = r
                out.append(np.ascontiguousarray(dense.reshape(shape, order="F")))  # row-major, as DM.full()
        return tuple(out)

    def stats(self) -> dict[str, Any]:
        """The CasADi statistics of this thread's last call (a solver's return status and
        iteration count): its buffer's, or the function's after an ordinary call."""
        if getattr(self._local, "buffered", False):
            return dict(self._local.buffers[3].stats())
        return dict(self.function.stats())
