"""How the variational GA encodes a law: the parameters q as Gray-coded bit strings
(:class:`GrayCodec`) and the structure as a list of small variations of the basic matrix
(:class:`StructureCodec`).

References
----------
A.I. Diveev, E.A. Sofronova, "The network operator method in control problems", Vestnik RUDN,
2007 (variations of the basic solution; Gray-coded parameters).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["GrayCodec", "StructureCodec", "bits_text", "bits_array"]


def bits_text(bits) -> str:
    """A bit string (0/1 values) as text, ``"0110..."`` (the checkpoint's form)."""
    return (np.asarray(bits, dtype=np.uint8) + ord("0")).tobytes().decode("ascii")


def bits_array(text: str) -> np.ndarray:
    return (np.frombuffer(text.encode(), dtype=np.uint8) - ord("0")).copy()


# -- parameters: Gray-coded bit strings ---------------------------------------------------------
@dataclass(frozen=True)
class GrayCodec:
    """``n`` parameters, each ``int_bits + frac_bits`` Gray-coded bits mapped to ``[lo, hi)``.

    With the defaults (4 + 12 bits, [0, 16)) a parameter is an integer part of 4 bits and a
    fractional part of 12 bits, step 2^-12, as in the lab programs.
    """

    n: int
    int_bits: int = 4
    frac_bits: int = 12
    lo: float = 0.0
    hi: float = 16.0

    @property
    def bits_per(self) -> int:
        return self.int_bits + self.frac_bits

    @property
    def n_bits(self) -> int:
        return self.n * self.bits_per

    @property
    def step(self) -> float:
        """The grid of the code: one unit of the last bit."""
        return (self.hi - self.lo) / float(1 << self.bits_per)

    def decode(self, bits) -> list:
        table = _decode_table(self)
        if table is not None:          # a parameter's bits (one byte each) -> its value
            raw, k = np.asarray(bits, dtype=np.uint8).tobytes(), self.bits_per
            if len(raw) == self.n_bits:
                return [table[raw[i:i + k]] for i in range(0, len(raw), k)]
        bits = np.asarray(bits, dtype=np.uint8).reshape(self.n, self.bits_per)
        # Gray -> binary: b_k = g_0 xor ... xor g_k
        binary = np.bitwise_xor.accumulate(bits, axis=1)
        weights = 1 << np.arange(self.bits_per - 1, -1, -1, dtype=np.int64)
        return self._values(binary.astype(np.int64) @ weights)

    def _values(self, ints) -> list:
        return list(self.lo + (self.hi - self.lo) * ints / float(1 << self.bits_per))

    def _ints(self, values) -> np.ndarray:
        values = np.asarray(values, float)
        full = 1 << self.bits_per
        ints = np.clip(np.round((values - self.lo) / (self.hi - self.lo) * full), 0, full - 1)
        return ints.astype(np.int64)

    def encode(self, values) -> np.ndarray:
        return _gray_bits(self._ints(values), self.bits_per).ravel()

    def encode_rows(self, rows) -> np.ndarray:
        """:meth:`encode` of each row of ``rows`` (one law's parameters a row), at once."""
        ints = self._ints(rows)
        return _gray_bits(ints.ravel(), self.bits_per).reshape(len(ints), -1)

    def grid(self, values) -> list:
        """``decode(encode(values))`` (what the code can hold), without the bits."""
        return self._values(self._ints(values))


def _gray_bits(ints, k: int) -> np.ndarray:
    """The ``k``-bit Gray codes of the integers ``ints``, most significant bit first: one row
    of 0/1 bytes per integer."""
    gray = ints ^ (ints >> 1)
    return ((gray[:, None] >> np.arange(k - 1, -1, -1)[None, :]) & 1).astype(np.uint8)


#: [choice] Codes of at most this many bits per parameter decode through a table of every
#: code's value (65 536 entries for the default 16 bits, built once per process and codec):
#: a dictionary look-up per parameter instead of a few array operations per law (the search
#: decodes every candidate, and CMA-ES's candidates twice).
TABLE_BITS = 16
_TABLES: dict = {}


def _decode_table(codec: GrayCodec) -> dict | None:
    """Each parameter's code (``bits_per`` bytes 0/1) -> its value, as :meth:`GrayCodec.decode`
    computes it (None: codes too long for a table)."""
    k = codec.bits_per
    if k > TABLE_BITS:
        return None
    key = (k, codec.lo, codec.hi)
    table = _TABLES.get(key)
    if table is None:
        ints = np.arange(1 << k, dtype=np.int64)
        bits = _gray_bits(ints, k)
        values = GrayCodec(1, k, 0, codec.lo, codec.hi)._values(ints)
        table = _TABLES[key] = dict(zip((bytes(b) for b in bits), values))
    return table


# -- structure: variations of a network-operator matrix ------------------------------------------
@dataclass
class StructureCodec:
    """Small variations (kind, i, j, op) of an upper-triangular matrix (0-based node numbers).

    kinds: 0 replace the unary operation on an existing arc i->j; 1 replace the binary
    operation at non-source node j; 2 add an arc i->j with unary operation ``op`` (target a
    non-source node that has a binary operation); 3 remove the arc i->j if node j keeps another
    incoming arc and node i another outgoing arc; 4 (drawn with probability ``weighted``, 0 =
    never) a **weighted arc** i->j through ``op``: :meth:`weighted_arc`.  A variation with
    ``j < n_sources`` (such as (0, 0, 0, 0)) is the identity.  The last ``n_params`` source
    nodes are the constants q.
    """

    size: int
    n_sources: int
    unary: tuple = tuple(range(1, 29))
    binary: tuple = (1, 2, 3, 4)
    weighted: float = 0.0
    n_params: int = 0

    IDENTITY = (0, 0, 0, 0)

    def random(self, rng: np.random.Generator, pick=None) -> tuple:
        """A random variation; ``pick(table, n)``, when given, draws the kind (0-3, table
        ``"kind"``) and the operation's index (``"unary"`` or ``"binary"``) instead of the
        uniform draws (the GA's ``credit``)."""
        # weighted == 0 draws exactly as before the weighted arcs existed (pinned results)
        draw = pick or (lambda table, n: int(rng.integers(0, n)))
        kind = 4 if self.weighted and rng.random() < self.weighted else draw("kind", 4)
        j = int(rng.integers(self.n_sources, self.size))
        i = int(rng.integers(0, j))
        ops = self.binary if kind == 1 else self.unary
        return (kind, i, j, int(ops[draw("binary" if kind == 1 else "unary", len(ops))]))

    def apply(self, psi: np.ndarray, variations) -> np.ndarray:
        """A copy of ``psi`` with the applicable variations applied in order."""
        psi = psi.copy()
        for kind, i, j, op in variations:
            if j < self.n_sources or i >= j or j >= self.size:
                continue
            if kind == 0:
                if psi[i, j]:
                    psi[i, j] = op
            elif kind == 1:
                if psi[j, j]:
                    psi[j, j] = op
            elif kind == 2:
                if not psi[i, j] and psi[j, j]:
                    psi[i, j] = op
            elif kind == 3:
                if psi[i, j] and np.count_nonzero(psi[:j, j]) > 1 \
                        and np.count_nonzero(psi[i, i + 1:]) > 1:
                    psi[i, j] = 0
            elif kind == 4:
                self.weighted_arc(psi, i, j, op)
        return psi

    def weighted_arc(self, psi: np.ndarray, i: int, j: int, op: int) -> None:
        """Add (in place) the arc i->j through ``op`` with a weight of its own: the first free
        node k (no arcs in or out, i < k < j) becomes the product of an unused constant q_p
        and node i, and k->j carries ``op`` -- so the arc adds ``op(q_p z_i)`` to node j, and
        at q_p = 0 the law is its parent's when ``op(0)`` is the unit of node j's binary
        operation (0 into a sum, 1 into a product); an arc i->j may exist beside it.  Skipped
        (like any inapplicable variation) when that is not so, or when no free node or unused
        constant is left: docs/methods/network_operator.md "Weighted arcs"."""
        from descent_fmus.models.controllers.operation_table import UNARY, UNIT
        if not psi[j, j] or not neutral_into(UNARY[op], UNIT[psi[j, j]]):
            return
        first = self.n_sources - self.n_params
        p = next((p for p in range(first, self.n_sources)
                  if p != i and not psi[p, p + 1:].any()), None)
        k = next((k for k in range(max(i + 1, self.n_sources), j)
                  if not psi[:k, k].any() and not psi[k, k + 1:].any()), None)
        if p is None or k is None:
            return
        psi[k, k], psi[p, k], psi[i, k], psi[k, j] = 2, 1, 1, op     # k = q_p * z_i (product)


def neutral_into(rho, unit) -> bool:
    """Whether ``rho(0)`` is ``unit`` (the unit element of the receiving node's operation)."""
    try:
        return unit is not None and float(rho(0.0)) == unit
    except (ValueError, ZeroDivisionError, OverflowError):
        return False
