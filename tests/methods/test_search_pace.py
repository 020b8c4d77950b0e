"""The search's fast paths give what the slow ones give, bit for bit (issue #41: the S1 search at
the evaluator's pace): the Gray code's decoding table, the structure search's law constructor
and the interpreter's cache of compiled programs."""
import math

import numpy as np
import pytest

from descent_fmus.models.controllers import law_interpreter
from descent_fmus.synthesis.methods import encoding
from descent_fmus.synthesis.methods.encoding import GrayCodec
from descent_fmus.synthesis.methods.law import MatrixError, NetworkOperator


def _hex(values):
    return [float(v).hex() for v in values]


@pytest.mark.parametrize("codec", [GrayCodec(7), GrayCodec(3, 2, 5, -1.0, 3.0),
                                   GrayCodec(4, 5, 11, -8.0, 8.0), GrayCodec(2, 1, 0)])
def test_decode_table_matches_the_array_route(codec, monkeypatch):
    # oracle: the xor-accumulate decoding on arrays (the route of codes longer than the table)
    rng = np.random.default_rng(3)
    codes = [rng.integers(0, 2, codec.n_bits).astype(np.uint8) for _ in range(300)]
    codes.append(codec.encode([codec.lo] * codec.n))
    codes.append(codec.encode([codec.hi] * codec.n))
    fast = [codec.decode(b) for b in codes]
    monkeypatch.setattr(encoding, "TABLE_BITS", 0)
    slow = [codec.decode(b) for b in codes]
    assert [_hex(v) for v in fast] == [_hex(v) for v in slow]
    assert all(type(a) is type(b) for f, s in zip(fast, slow) for a, b in zip(f, s))
    x = rng.uniform(codec.lo - 1.0, codec.hi + 1.0, (50, codec.n))
    # grid(): decode(encode(x)) without the bits, exactly
    assert [_hex(codec.grid(v)) for v in x] == [_hex(codec.decode(codec.encode(v))) for v in x]


def _template():
    return NetworkOperator.linear([[0.5, -1.25]], [0.1], bounds=[(-2.0, 3.0)],
                                  input_names=["h", "v"], input_scale=[2.0, 0.5],
                                  input_offset=[1.0, 0.0])


def test_with_structure_is_the_constructors_law():
    # oracle: the validating constructor with the same arguments
    t = _template()
    psi = t.psi.copy()
    psi[0, psi.shape[0] - 1] = 3                       # one more arc, a structure variation
    for q in ([1.0, 2.0, -3.0], np.array([0.25, 7.5, 1e-3])):
        fast = t.with_structure(psi, q)
        slow = NetworkOperator(psi, t.nx, q, t.outputs, t.bounds, t.input_names,
                               t.input_scale, t.input_offset)
        assert np.array_equal(fast.psi, slow.psi) and fast.psi.dtype == slow.psi.dtype
        assert fast.to_dict() == slow.to_dict()
        assert [type(v) for v in fast.q] == [type(v) for v in slow.q]
        assert fast._program == slow._program and fast._scaled == slow._scaled
        pts = [[0.3, -1.0], [5.0, 2.0]]
        assert _hex(v for r in fast.raw_points(pts) for v in r) == \
            _hex(v for r in slow.raw_points(pts) for v in r)
        assert fast.outputs is not t.outputs and fast.bounds is not t.bounds


def test_with_structure_still_refuses_bad_laws():
    t = _template()
    bad = t.psi.copy()
    bad[3, 1] = 1                                      # below the diagonal
    with pytest.raises(MatrixError, match="upper-triangular"):
        t.with_structure(bad, t.q)
    with pytest.raises(MatrixError, match="finite"):
        t.with_structure(t.psi, [float("nan")] + t.q[1:])


def test_program_cache_is_bounded_and_keyed_by_the_sources(monkeypatch):
    monkeypatch.setattr(law_interpreter, "PROGRAM_CACHE", 3)
    monkeypatch.setattr(law_interpreter, "_PROGRAMS", {})
    t = _template()
    a = law_interpreter.compile_law(t.psi, 2, 3, [t.size])
    assert law_interpreter.compile_law(t.psi.copy(), 2, 3, [t.size]) is a
    b = law_interpreter.compile_law(t.psi, 2, 2, [t.size])     # other sources: its own
    assert b is not a and b[1] != a[1]
    for k in range(4):
        psi = t.psi.copy()
        psi[0, t.size - 1] = k + 1
        law_interpreter.compile_law(psi, 2, 3, [t.size])
    assert len(law_interpreter._PROGRAMS) == 3


def test_bits_text_round_trip():
    # oracle: the digits' own text, one character per bit
    rng = np.random.default_rng(5)
    for n in (0, 1, 7, 480):
        bits = rng.integers(0, 2, n).astype(np.uint8)
        text = encoding.bits_text(bits)
        assert text == "".join(str(int(b)) for b in bits)
        assert np.array_equal(encoding.bits_array(text), bits)
    assert encoding.bits_text([1, 0, 1]) == "101"


def test_target_better_agrees_with_its_order():
    # oracle: Target.order (the array route) on the pair of rows
    from descent_fmus.synthesis.methods.pareto import Target
    rng = np.random.default_rng(8)
    rows = rng.uniform(0.0, 3.0, (60, 3))
    rows[::7, 1] = 1.0                                  # exactly at the limit
    rows[::11, 0] = np.nan
    for t in (Target(0, 1, 1.0, 10.0), Target(2), Target(0, 1, math.inf)):
        for a in range(len(rows)):
            b = (a * 17 + 5) % len(rows)
            for ca, cb in ((0.0, 0.0), (0.5, 0.0), (0.0, 0.3)):
                want = t.feasible(rows[[a]])[0], t.scalar(rows[[a]])[0]
                assert t._feasible_row(rows[a]) == want[0]
                assert np.array_equal(t._scalar_row(rows[a]), want[1], equal_nan=True)
                order = t.order(rows[[a, b]], [ca, cb]).tolist()
                keys_differ = t.keys(rows[[a]], [ca]) != t.keys(rows[[b]], [cb])
                if keys_differ and not np.isnan(rows[[a, b], t.objective]).any():
                    assert t.better(rows[a], rows[b], ca, cb) == (order == [0, 1])


@pytest.mark.parametrize("codec", [GrayCodec(5), GrayCodec(7, 20, 28, -2.0 ** 19, 2.0 ** 19)])
def test_a_generation_coded_at_once_is_its_laws_coded_one_by_one(codec):
    # oracle: CMA.ask() and GrayCodec.encode() law by law (the refinement's route before);
    # ask_rows() + encode_rows() must give the same grid values and the same bits, exactly
    from descent_fmus.synthesis.methods.cma import CMA
    span = codec.hi - codec.lo
    for seed in range(3):
        x0 = codec.lo + span * np.linspace(0.1, 0.9, codec.n)
        search = CMA(x0, 0.3, seed, bounds=(codec.lo, codec.hi - codec.step),
                     x_map=codec.grid, popsize=12)
        for _ in range(3):
            one = search.ask()
            rows = search.ask_rows()
            assert [_hex(x) for x in one] == [_hex(x) for x in rows]
            bits = codec.encode_rows(rows)
            assert bits.shape == (12, codec.n_bits) and bits.dtype == np.uint8
            assert all(np.array_equal(codec.encode(x), b) for x, b in zip(one, bits))
            search.tell([float(np.sum(np.asarray(x) ** 2)) for x in one])


def _fingerprint(law) -> bytes:
    """The fingerprint's definition hashed from scratch (the oracle of the cached route)."""
    import hashlib
    import struct
    h = hashlib.blake2b(digest_size=16)
    h.update(struct.pack("<2q", *law.psi.shape))
    h.update(np.asarray(law.psi).astype("<i8").tobytes())
    for part in (law.q, law.outputs, [v for b in law.bounds for v in b], law.input_scale,
                 law.input_offset):
        h.update(struct.pack(f"<q{len(part)}d", len(part), *map(float, part)))
    return h.digest()


def test_fingerprints_with_the_matrix_hash_cached_are_the_definitions(monkeypatch):
    # oracle: blake2b over the same bytes from scratch (_fingerprint); laws sharing a matrix
    # (the cached hash state) and a cache so small that it is emptied on the way
    from descent_fmus.synthesis.run import evaluation
    from tests.methods.test_interpreter_batch import _random_law
    monkeypatch.setattr(evaluation, "KEY_PREFIXES", 3)
    rng = np.random.default_rng(5)
    t = _template()
    laws = [_random_law(rng) for _ in range(6)] + [t]
    laws += [t.with_structure(t.psi, [v] * len(t.q)) for v in (0.5, 0.5000000001, -2.0)]
    laws += [NetworkOperator(np.asarray(law.psi, np.int32), law.nx, law.q, law.outputs,
                             law.bounds, law.input_names, law.input_scale, law.input_offset)
             for law in laws[:3]]
    keys = [evaluation.law_key(law) for law in laws + laws[::-1]]
    assert keys == [_fingerprint(law) for law in laws + laws[::-1]]
    assert len(set(keys[:len(laws)])) == len(laws) - 3   # the int32 copies: the same laws
    assert len(evaluation._PREFIXES) <= 3


def test_journal_and_behaviour_lines_share_one_encoding():
    # oracle: json's encoder on the whole line (the text before the shared encoding)
    import json
    from descent_fmus.synthesis.problems.contract import Outcome
    from descent_fmus.synthesis.run import folder
    enc = json.JSONEncoder(default=folder._plain)
    outs = [Outcome((1.0, 2.5e-300), 0.0, {"landed": True, "t": 1 / 3}),
            Outcome((float(np.float64(7.25)),), 3.0, {"error": 'a "quoted" \\ text\n',
                                                      "a": np.arange(3)}),
            Outcome((0.1, -0.0), 1e300, {})]
    texts: dict = {}
    for name in ("k", "b", "k"):
        for i, o in enumerate(outs):
            key = bytes([i]) * 16
            want = enc.encode({name: key.hex(), "f": list(o.f), "cv": o.cv,
                               "extras": o.extras}) + "\n"
            assert folder._line(name, key, o, texts) == want == folder._line(name, key, o)
    assert len(texts) == len(outs)


def test_archive_states_kept_per_law_are_the_states_made_anew():
    # oracle: archive_state without the kept states, after the archive changed
    import json
    from descent_fmus.synthesis.methods.base import Candidate
    from descent_fmus.synthesis.methods.pareto import ParetoArchive
    from descent_fmus.synthesis.run.loop import archive_state
    t = _template()
    archive, known = ParetoArchive(10), {}
    for k in range(6):
        law = t.with_structure(t.psi, [0.1 * k])
        archive.add(Candidate(law, {"k": k}), np.array([float(k), 6.0 - k]), 0.0)
        assert json.dumps(archive_state(archive, known)) == json.dumps(archive_state(archive))
        assert set(known) == {id(c.law) for c, _, _ in archive.items}
    archive.add(Candidate(t, {"k": -1}), np.array([-1.0, -1.0]), 0.0)    # dominates all
    assert json.dumps(archive_state(archive, known)) == json.dumps(archive_state(archive))
    assert set(known) == {id(t)}


def test_behaviour_keys_hash_each_value_to_12_digits():
    # oracle: the key's definition, ",".join(f"{v:.12g}") of the values hashed, on values
    # that round, specials and integers
    import hashlib
    from descent_fmus.synthesis.run.evaluation import _behaviour_key

    class Prober:
        def __init__(self, values):
            self.v = values

        def values(self, law, points):
            return self.v

    rng = np.random.default_rng(9)
    cases = [[], [0.0, -0.0, math.inf, -math.inf, math.nan, 5e-324, 1.7976931348623157e308],
             [123456789012.5, 0.1 + 0.2, 1e16, 1e-5, 3, -7], list(rng.normal(0, 1e4, 32)),
             [float(v) for v in rng.normal(0, 1, 16) ** 31]]
    for values in cases:
        want = hashlib.blake2b(",".join(f"{v:.12g}" for v in values).encode(),
                               digest_size=16).digest()
        assert _behaviour_key(None, None, Prober(values)) == want
    # 12 significant digits: equal keys for values equal to 12 digits, different otherwise
    assert _behaviour_key(None, None, Prober([1.0000000000001])) == \
        _behaviour_key(None, None, Prober([1.0]))
    assert _behaviour_key(None, None, Prober([1.00000000001])) != \
        _behaviour_key(None, None, Prober([1.0]))
