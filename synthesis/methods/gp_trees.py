"""Genetic-programming trees (DEAP) over the network operator's operations, and their
compilation into network-operator laws.

The primitive set of :func:`primitive_set` holds the problem's operations -- the very functions
of the operation tables in :mod:`models.controllers.operation_table` -- so a tree means what
the law it compiles to computes.  :func:`compile_trees` turns one tree per output into one
:class:`~synthesis.methods.law.NetworkOperator` (binary nodes, unary arcs, the ephemeral
constants as its parameters q); every GP law is then flown by the same evaluator and exported
like any other law.

Semantics (exact, the law's evaluation order): a binary primitive ``chi(a, b)`` is the node
``finite(chi(finite(chi(unit, a)), b))`` -- the node starts at the operation's unit element and
takes its arcs in the order of their source nodes, clamping after each; a unary primitive
``rho(z)`` is an arc, ``rho(finite(z))``, left unclamped until the node it enters clamps it; an
output is ``finite`` of its tree.  The compiler keeps that order: a second operand whose node
does not come after the first's is copied into a new identity node; a unary primitive of a
unary primitive (or at the root) gets a node of its own (``+`` of one arc); identical sub-trees
and constants share one node (also across outputs): two sub-trees are identical when DEAP
prints them alike (:func:`tree_key`, the printed nodes in prefix order, is the key).
"""
from __future__ import annotations

import functools
import keyword
import random

import numpy as np
from deap import gp

from descent_fmus.models.controllers.network_operator import L_MAX, NQ_MAX
from descent_fmus.models.controllers.operation_table import (BINARY, BINARY_OPS, BIG, UNARY,
                                                             UNARY_OPS, UNIT, finite)
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.methods.law_fmu import CapacityError

__all__ = ["primitive_set", "compile_trees", "tree_value", "tree_to_tokens",
           "tree_from_tokens", "tree_key", "law_size", "IDENTITY", "ADD"]

#: The identity unary operation and the binary operation + (the law's numbers).
IDENTITY, ADD = 1, 1


def _guarded(f):
    """``f`` with the evaluation's guard: an exception (never met: the operands are finite)
    gives BIG, as in :func:`models.controllers.law_interpreter.evaluate`."""
    def call(*args):
        try:
            return f(*args)
        except (OverflowError, ValueError, ZeroDivisionError):
            return BIG
    return call


def _unary(k: int):
    rho = _guarded(UNARY[k])

    def prim(z):
        return rho(finite(z))
    return prim


def _binary(k: int):
    chi, unit = _guarded(BINARY[k]), UNIT[k]

    def prim(a, b):
        return finite(chi(finite(chi(unit, a)), b))
    return prim


def _name(op_name: str, taken: set) -> str:
    name = op_name if op_name.isidentifier() and not keyword.iskeyword(op_name) else \
        op_name + "_"
    while name in taken:
        name += "_"
    taken.add(name)
    return name


#: The name of the ephemeral constants in the primitive set.
CONSTANT = "const"


def _is_constant(node) -> bool:
    return isinstance(type(node), gp.MetaEphemeral)


def primitive_set(nx: int, unary, binary, const_range: float) -> gp.PrimitiveSet:
    """DEAP's primitive set of a law with ``nx`` inputs (terminals ``x1..x<nx>``), the unary
    operations ``unary`` and binary operations ``binary`` (numbers of the law's tables; the
    identity is left out: in a tree it does nothing) and ephemeral constants uniform in
    ``[-const_range, const_range]``."""
    pset = gp.PrimitiveSet("LAW", nx)
    pset.renameArguments(**{f"ARG{k}": f"x{k + 1}" for k in range(nx)})
    taken = set(pset.mapping) | {CONSTANT}
    pset.law_ops = {}                      # primitive name -> the law's operation number
    for k in binary:
        name = _name(BINARY_OPS[k].name, taken)
        pset.addPrimitive(_binary(k), 2, name=name)
        pset.law_ops[name] = k
    for k in unary:
        if k != IDENTITY:
            name = _name(UNARY_OPS[k].name, taken)
            pset.addPrimitive(_unary(k), 1, name=name)
            pset.law_ops[name] = k
    # drawn from the module-level generator, which the GP swaps its own state into
    pset.addEphemeralConstant(CONSTANT, functools.partial(random.uniform, -float(const_range),
                                                          float(const_range)))
    return pset


# -- tree <-> JSON --------------------------------------------------------------------------------
def tree_to_tokens(tree) -> list:
    """A tree as JSON-able prefix tokens: names of primitives and inputs, constants as numbers."""
    return [float(n.value) if _is_constant(n) else (n.value if n.arity == 0 else n.name)
            for n in tree]


def tree_from_tokens(tokens, pset) -> gp.PrimitiveTree:
    """The tree of :func:`tree_to_tokens` (no random number drawn)."""
    nodes = []
    for t in tokens:
        if isinstance(t, str):
            if t not in pset.mapping or t == CONSTANT:
                raise ValueError(f"unknown primitive or input {t!r} in a GP tree")
            nodes.append(pset.mapping[t])
        else:
            c = object.__new__(pset.mapping[CONSTANT])
            c.value = float(t)
            nodes.append(c)
    return gp.PrimitiveTree(nodes)


def tree_value(tree, pset, x) -> float:
    """DEAP's own evaluation of a tree (``gp.compile``) at the inputs ``x`` (as the law's source
    nodes hold them), clamped as a law's output node."""
    return finite(gp.compile(tree, pset)(*x))


# -- tree -> network operator ---------------------------------------------------------------------
def tree_key(tree) -> tuple:
    """The tree's nodes as DEAP prints them (names of primitives and inputs, ``repr`` of
    constants), in prefix order: equal exactly when ``str(tree)`` is (prefix order with fixed
    arities reads back one way), at a fraction of its cost (no nested strings)."""
    return tuple(n.name if n.arity else n.format() for n in tree)


def _subtree_ends(tree) -> list:
    """``ends[i]``: the end of the sub-tree at ``i`` (DEAP's ``searchSubtree(i).stop``), all in
    one pass from the right."""
    ends, stack = [0] * len(tree), []
    for i in range(len(tree) - 1, -1, -1):
        end = i + 1
        for _ in range(tree[i].arity):            # the children's ends, first child on top
            end = stack.pop()
        ends[i] = end
        stack.append(end)
    return ends


class _Compiler:
    """Allocates the nodes of one law for a list of trees (see the module docstring)."""

    def __init__(self, nx: int, trees, ops: dict):
        self.nx, self.law_ops = nx, ops
        self.q: dict = {}
        for tree in trees:
            for n in tree:
                if _is_constant(n) and n.value not in self.q:
                    self.q[n.value] = nx + len(self.q)
        self.arcs: list = []                       # (source, target, unary)
        self.ops: list = []                        # binary operation of each inner node
        self.memo: dict = {}                       # a sub-tree's tree_key -> its arc
        self.keys: dict = {}                       # id(tree) -> (tree_key, sub-tree ends)

    @property
    def next(self) -> int:
        return self.nx + len(self.q) + len(self.ops)

    def node(self, binary: int, arcs) -> int:
        j = self.next
        self.ops.append(binary)
        self.arcs += [(i, j, rho) for i, rho in arcs]
        return j

    def subtree(self, tree, at: int) -> tuple:
        """``((node, unary), end)``: the sub-tree at ``at`` as the unary arc leaving a node."""
        n = tree[at]
        if id(tree) not in self.keys:
            self.keys[id(tree)] = (tree_key(tree), _subtree_ends(tree))
        tokens, ends = self.keys[id(tree)]
        end = ends[at]
        key = tokens[at:end]                        # the sub-tree's str, in effect
        if key in self.memo:
            return self.memo[key], end
        if _is_constant(n):
            out = (self.q[n.value], IDENTITY)
        elif n.arity == 0:
            out = (int(n.value[1:]) - 1, IDENTITY)      # input x<k> (renamed)
        elif n.arity == 1:
            (i, rho), _ = self.subtree(tree, at + 1)
            if rho != IDENTITY:                    # a unary of a unary: a node of its own
                i = self.node(ADD, [(i, rho)])
            out = (i, self.law_ops[n.name])
        else:
            (a, ra), mid = self.subtree(tree, at + 1)
            (b, rb), _ = self.subtree(tree, mid)
            if b <= a:                              # the arcs' order: the first operand first
                b = self.node(ADD, [(b, IDENTITY)])
            out = (self.node(self.law_ops[n.name], [(a, ra), (b, rb)]), IDENTITY)
        self.memo[key] = out
        return out, end

    def output(self, tree) -> int:
        (i, rho), _ = self.subtree(tree, 0)
        if rho != IDENTITY or i < self.nx + len(self.q):
            i = self.node(ADD, [(i, rho)])
        return i


def law_size(nx: int, trees, pset) -> tuple:
    """``(nodes, parameters)`` of the law the trees compile to."""
    c = _Compiler(nx, trees, pset.law_ops)
    for tree in trees:
        c.output(tree)
    return c.next, len(c.q)


def compile_trees(trees, pset, template: NetworkOperator) -> NetworkOperator:
    """The law of one tree per output, with ``template``'s inputs, bounds and input scaling
    (the problem's basic law).

    Raises
    ------
    CapacityError
        The law needs more nodes or parameters than the generic controller FMU holds.
    """
    if len(trees) != len(template.outputs):
        raise ValueError(f"{len(trees)} trees for {len(template.outputs)} outputs")
    c = _Compiler(template.nx, trees, pset.law_ops)
    outputs = [c.output(tree) + 1 for tree in trees]
    size, nq = c.next, len(c.q)
    if size > L_MAX or nq > NQ_MAX:
        raise CapacityError(f"the trees compile to {size} nodes and {nq} parameters; the "
                            f"controller FMU holds {L_MAX} and {NQ_MAX}")
    psi = np.zeros((size, size), dtype=int)
    ns = template.nx + nq
    for k, op in enumerate(c.ops):
        psi[ns + k, ns + k] = op
    for i, j, rho in c.arcs:
        psi[i, j] = rho
    return NetworkOperator(psi, template.nx, list(c.q), outputs, list(template.bounds),
                           list(template.input_names), list(template.input_scale),
                           list(template.input_offset))
