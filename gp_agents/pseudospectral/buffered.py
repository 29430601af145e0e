"""Calling a CasADi Function with numpy arrays without converting them to ``DM``.

``f(a)`` with a numpy array converts it element by element into a ``casadi.DM`` and the results
back, which is slow for large inputs such as a GP's parameter vector (tens of thousands of
numbers for the quadrotor's SSGP; an ad-hoc timing, not kept in the repository, put the
conversion at milliseconds per call, the buffered call at tens of microseconds).
CasADi's buffer interface (``Function.buffer()``, casadi issue #1511) evaluates on memory the
caller owns instead: :class:`BufferedFunction` wraps it for dense vector inputs and outputs.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

__all__ = ["BufferedFunction"]


class BufferedFunction:
    """A CasADi Function evaluated on numpy memory (``Function.buffer()``).

    Args:
        fn: a Function whose inputs and outputs are all dense (any shape: they are read and
            written column-major, as flat vectors of their ``nnz``).

    One set of buffers per instance: not for concurrent calls from several threads. Calling
    it with one array-like per input (a matrix input may be given as its (rows, cols)
    array: it is read column-major, as CasADi stores it) returns a tuple of fresh (nnz,) float
    arrays, one per output, column-major (copies: the buffers are reused by the next call).

    Raises:
        ValueError: a sparse input or output (at construction); at a call, the wrong number of
            inputs or an input of the wrong size.
    """

    def __init__(self, fn: ca.Function) -> None:
        for kind, n, sparsity in (("input", fn.n_in(), fn.sparsity_in),
                                  ("output", fn.n_out(), fn.sparsity_out)):
            for i in range(n):
                if not sparsity(i).is_dense():
                    raise ValueError(f"{fn.name()}: {kind} {i} is sparse; BufferedFunction "
                                     "takes dense inputs and outputs only")
        self.fn = fn
        self._sizes = [fn.nnz_in(i) for i in range(fn.n_in())]
        self._out = [np.zeros(fn.nnz_out(i)) for i in range(fn.n_out())]
        self._buffer, self._eval = fn.buffer()
        for i, out in enumerate(self._out):
            self._buffer.set_res(i, memoryview(out))

    def __call__(self, *args: Any) -> tuple[np.ndarray, ...]:
        """Evaluate at ``args`` (one array-like of ``nnz_in(i)`` numbers per input)."""
        if len(args) != len(self._sizes):
            raise ValueError(f"{self.fn.name()} takes {len(self._sizes)} inputs, got "
                             f"{len(args)}")
        held = []  # the arrays whose memory the buffer reads, alive until the call returns
        for i, (a, size) in enumerate(zip(args, self._sizes, strict=True)):
            arr = np.ascontiguousarray(np.asarray(a, dtype=float).reshape(-1, order="F"))
            if arr.size != size:
                raise ValueError(f"{self.fn.name()}: input {i} ({self.fn.name_in(i)}) needs "
                                 f"{size} numbers, got {arr.size}")
            held.append(arr)
            self._buffer.set_arg(i, memoryview(arr))
        self._eval()
        return tuple(out.copy() for out in self._out)

    def call(self, **kwargs: Any) -> dict[str, np.ndarray]:
        """Evaluate by input names (an omitted input takes the Function's default, e.g.
        -inf for a solver's ``lbx``, as in ``fn(**kwargs)``); returns the outputs by name."""
        unknown = set(kwargs) - set(self.fn.name_in())
        if unknown:
            raise ValueError(f"{self.fn.name()} has no inputs {sorted(unknown)}")
        args = [kwargs[name] if name in kwargs else np.full(size, self.fn.default_in(i))
                for i, (name, size) in enumerate(zip(self.fn.name_in(), self._sizes,
                                                     strict=True))]
        return dict(zip(self.fn.name_out(), self(*args), strict=True))

    def stats(self) -> dict[str, Any]:
        """The statistics of the last evaluation (a solver's iterations, status, ...)."""
        return dict(self._buffer.stats())

    def __getstate__(self) -> dict[str, Any]:
        return {"fn": self.fn}  # the buffers are memory of this process: rebuilt on loading

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__init__(state["fn"])
