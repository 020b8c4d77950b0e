"""Function-preserving starts (``ga.morph``): a new form of mintime-di's switching path takes
constants that match its parent's law at probe points before it is flown
(docs/methods/network_operator.md, "Function-preserving starts").  Oracle: the exact
zero-order-hold flight of tests/suite/test_suite_forms.py (a matrix exponential)."""
from __future__ import annotations

import numpy as np

from descent_fmus.synthesis.methods.form_search import preserving_constants, touched_constants
from descent_fmus.synthesis.methods.law import NetworkOperator
from descent_fmus.synthesis.methods.structures import probe_inputs

from test_suite_forms import STARTS, TGO, _mean_time  # noqa: E402  (path set by that module)

REF = float(np.mean([TGO(a, b, 1.0) for a, b in STARTS]))


def _fly(law) -> float:
    return _mean_time(lambda a, b: law([a, b])[0]) / REF


def _step(parent: NetworkOperator, entries) -> tuple:
    """The parent's matrix with ``entries`` changed, flown with the parent's constants
    (inherited) and with function-preserving ones (morphed)."""
    psi = parent.psi.copy()
    for (i, j), op in entries.items():
        psi[i, j] = op
    inherited = NetworkOperator(psi, nx=2, q=list(parent.q), outputs=parent.outputs,
                                bounds=parent.bounds)
    idx = touched_constants(parent.psi, psi, 2, len(parent.q))
    q = preserving_constants(parent, inherited, idx, probe_inputs(parent, 16))
    return inherited, inherited.with_q(q), idx


def test_the_switching_path_starts_where_its_parent_is():
    # a linear parent near its tuned gains: Nelder-Mead on this flight (120 flights from the
    # best of five starts) ends at u = -7.9056 x1 - 4.6304 x2, 1.529 x the closed form
    parent = NetworkOperator.linear([[-7.9056, -4.6304]], [0.0], bounds=[(-1.0, 1.0)], size=24)
    t0 = _fly(parent)
    assert abs(t0 - 1.529) < 0.002
    # first variation: x1's product arc through ssqrt (psi[5, 7] = 4), touches q1 only
    inh1, mor1, idx = _step(parent, {(5, 7): 4})
    assert idx == [0]
    t1i, t1m = _fly(inh1), _fly(mor1)
    # inherited constants fly 1.709 x (11.8 % worse than the parent: the diagnosis); the
    # function-preserving q1 (-33.6, fitted on 16 probe points) 1.638 x (7.1 % worse)
    assert abs(t1i - 1.709) < 0.002
    assert t1m < t1i - 0.05
    assert t1m < 1.08 * t0
    # second variation: sgn of the x2 product added at the next node (psi[6, 8] = 10): no
    # constant of a clipped law undoes an added +-1, the morph keeps what it has (1.745 x)
    _, mor2, _ = _step(mor1, {(6, 8): 10})
    assert 1.0 < _fly(mor2) < 1.15 * t1m
