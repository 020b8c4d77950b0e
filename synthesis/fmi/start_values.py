"""Start values in the one form every closed loop takes: :class:`StartValues`, a read-only
mapping name -> value held as a tuple of names and one float array.

**[choice]** One form, a mapping, for every path (``docs/architecture.md``): the Python master
and the container set values by name, the native paths compare them with the FMUs' declared
start values as arrays.  A :class:`StartValues` is both (names and an array, read as a
mapping), so no path branches on the form it receives; a plain dict is read through
:meth:`StartValues.of` once per flight.
"""
from __future__ import annotations

from collections.abc import Mapping

import numpy as np

__all__ = ["StartValues"]


class StartValues(Mapping):
    """Start values of one FMU: ``names`` (a tuple) and their ``values`` (one float64 array,
    integers exactly).  Read as a mapping, a value is a float."""

    __slots__ = ("names", "values", "_index")

    def __init__(self, names, values):
        self.names = tuple(names)
        self.values = np.asarray(values, dtype=float)
        self._index = None
        if self.values.shape != (len(self.names),):
            raise ValueError(f"{len(self.names)} names for values of shape {self.values.shape}")

    @classmethod
    def of(cls, values) -> "StartValues":
        """``values`` (a mapping, or None for none) as :class:`StartValues`."""
        if isinstance(values, StartValues):
            return values
        values = values or {}
        return cls(tuple(values), np.fromiter(values.values(), float, len(values)))

    @classmethod
    def of_law(cls, law) -> "StartValues":
        """The start values that load ``law`` into its controller FMU: the law's names and array
        where it gives them at once (``NetworkOperator.start_array``), else its mapping."""
        arrays = getattr(law, "start_array", None)
        return cls(*arrays()) if arrays is not None else cls.of(law.start_values())

    def merged(self, pairs) -> "StartValues":
        """These values followed by ``pairs`` (``(name, value)``, e.g. a problem's controller
        mode)."""
        if not pairs:
            return self
        names, values = zip(*pairs)
        return StartValues(self.names + names,
                           np.concatenate([self.values, np.asarray(values, float)]))

    def __getitem__(self, name):
        if self._index is None:
            self._index = {n: k for k, n in enumerate(self.names)}
        return float(self.values[self._index[name]])

    def __iter__(self):
        return iter(self.names)

    def __len__(self) -> int:
        return len(self.names)

    def items(self):
        """``(name, value)`` pairs in order (one conversion of the array)."""
        return list(zip(self.names, self.values.tolist()))

    def __repr__(self) -> str:
        return f"StartValues({len(self.names)} values)"
