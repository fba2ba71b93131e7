"""sengine.random against an independent pure-Python SplitMix64 and BLAKE2b reference.

Every number here is recomputed with Python integers (no numpy), so a changed
constant, shift, mask or key order in the vectorized code fails a test.
"""

from __future__ import annotations

import hashlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sengine import random as srandom

M = (1 << 64) - 1
G = 0x9E3779B97F4A7C15


def ref_splitmix64(x: int) -> int:
    """Steele, Lea and Flood's SplitMix64 step on Python ints (the published algorithm)."""
    z = (x + G) & M
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & M
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & M
    return z ^ (z >> 31)


def ref_hash(text: str) -> int:
    return int.from_bytes(hashlib.blake2b(text.encode(), digest_size=8).digest(), "little")


def ref_uniform(seed: int, key: str, fid: int) -> float:
    k = ref_splitmix64(seed & M)
    k = ref_splitmix64(k ^ ref_hash(key))
    u = ref_splitmix64(k ^ ref_splitmix64(fid & M))
    return (u >> 11) / 2.0**53


u64 = st.integers(0, M)


def test_splitmix64_matches_the_published_sequence():
    # the first three outputs of SplitMix64 seeded with 0 (reference implementation, Vigna)
    out = srandom.splitmix64(np.array([0, G, 2 * G & M], np.uint64))
    assert out.dtype == np.uint64
    assert [int(v) for v in out] == [0xE220A8397B1DCDAF, 0x6E789E6AA1B965F4, 0x06C45D188009454F]


@settings(max_examples=200, deadline=None)
@given(st.lists(u64, min_size=1, max_size=20))
def test_splitmix64_equals_the_integer_reference(xs):
    out = srandom.splitmix64(np.array(xs, np.uint64))
    assert [int(v) for v in out] == [ref_splitmix64(x) for x in xs]


def test_splitmix64_scalar_and_wrapping_edges():
    assert int(srandom.splitmix64(M)) == ref_splitmix64(M)
    assert int(srandom.splitmix64(np.uint64(1))) == ref_splitmix64(1)
    # every bit of the input reaches the output (avalanche): flipping one bit changes ~half
    base = int(srandom.splitmix64(np.uint64(12345)))
    flips = [bin(base ^ int(srandom.splitmix64(np.uint64(12345 ^ (1 << b))))).count("1") for b in range(64)]
    assert 20 <= min(flips) and max(flips) <= 44 and 28 <= np.mean(flips) <= 36


def test_stable_hash_is_blake2b_little_endian_64_bit():
    assert srandom.stable_hash("") == ref_hash("")
    assert srandom.stable_hash("buildings/height") == ref_hash("buildings/height")
    assert srandom.stable_hash("é") == ref_hash("é")
    assert srandom.stable_hash("a") != srandom.stable_hash("b")
    h = srandom.stable_hash("lots")
    assert isinstance(h, int) and 0 <= h <= M
    # the literal value: a change of digest size, byte order or encoding shows here
    assert srandom.stable_hash("sengine") == int.from_bytes(
        hashlib.blake2b(b"sengine", digest_size=8).digest(), "little"
    )
    assert srandom.stable_hash("sengine") != int.from_bytes(hashlib.blake2b(b"sengine", digest_size=8).digest(), "big")


def test_word_hashes_strings_and_masks_integers():
    assert srandom._word("abc") == ref_hash("abc")
    assert srandom._word(7) == 7
    assert srandom._word(-1) == M
    assert srandom._word(1 << 64) == 0
    assert srandom._word(np.int64(5)) == 5


def _draws(g: np.random.Generator) -> list[float]:
    return list(g.random(4))


def test_generator_is_seeded_by_seed_node_and_key():
    ref = np.random.default_rng(np.random.SeedSequence([3, ref_hash("n1"), 17, ref_hash("roof")]))
    assert _draws(srandom.generator(3, "n1", 17, "roof")) == _draws(ref)
    assert _draws(srandom.generator(3, "n1", 17)) == _draws(srandom.generator(3, "n1", 17))
    base = _draws(srandom.generator(3, "n1", 17))
    assert _draws(srandom.generator(4, "n1", 17)) != base
    assert _draws(srandom.generator(3, "n2", 17)) != base
    assert _draws(srandom.generator(3, "n1", 18)) != base
    assert _draws(srandom.generator(3, "n1")) != base
    # negative seeds and ids are taken modulo 2**64, never an error
    assert _draws(srandom.generator(-1, "n1", -2)) == _draws(srandom.generator(M, "n1", M - 1))
    # a string key is its hash
    assert _draws(srandom.generator(3, "n1", "roof")) == _draws(srandom.generator(3, "n1", ref_hash("roof")))


@settings(max_examples=100, deadline=None)
@given(st.lists(u64, min_size=1, max_size=10), st.lists(u64, min_size=1, max_size=10))
def test_mix64_equals_the_integer_reference(seeds, keys):
    n = min(len(seeds), len(keys))
    s, k = seeds[:n], keys[:n]
    out = srandom.mix64(np.array(s, np.uint64), np.array(k, np.uint64))
    assert [int(v) for v in out] == [ref_splitmix64(a ^ (b * G & M)) for a, b in zip(s, k)]


def test_mix64_broadcasts_and_separates_seed_from_key():
    out = srandom.mix64(np.uint64(9), np.arange(5, dtype=np.uint64))
    assert out.shape == (5,) and len(set(out.tolist())) == 5
    assert int(srandom.mix64(1, 2)) != int(srandom.mix64(2, 1))


@settings(max_examples=100, deadline=None)
@given(u64, st.lists(u64, min_size=1, max_size=10))
def test_hash01_is_the_top_53_bits(seed, keys):
    out = srandom.hash01(np.uint64(seed), np.array(keys, np.uint64))
    assert out.dtype == np.float64
    expect = [(ref_splitmix64(seed ^ (k * G & M)) >> 11) / 2.0**53 for k in keys]
    assert out.tolist() == expect
    assert np.all((out >= 0.0) & (out < 1.0))


def test_hash01_is_uniform():
    u = srandom.hash01(np.uint64(42), np.arange(100_000, dtype=np.uint64))
    assert abs(u.mean() - 0.5) < 0.005
    hist, _ = np.histogram(u, bins=10, range=(0.0, 1.0))
    assert hist.min() > 9_500 and hist.max() < 10_500


@settings(max_examples=100, deadline=None)
@given(st.integers(-(2**63), 2**63 - 1), st.text(max_size=12), st.lists(st.integers(-(2**63), 2**63 - 1), max_size=10))
def test_uniform_equals_the_integer_reference(seed, key, ids):
    out = srandom.uniform(seed, key, np.array(ids, np.int64))
    assert out.dtype == np.float64 and out.shape == (len(ids),)
    assert out.tolist() == [ref_uniform(seed, key, i) for i in ids]


def test_uniform_depends_on_the_feature_id_only():
    ids = np.arange(50)
    whole = srandom.uniform(5, "buildings/height", ids)
    perm = np.random.default_rng(0).permutation(50)
    assert np.array_equal(srandom.uniform(5, "buildings/height", ids[perm]), whole[perm])
    assert np.array_equal(srandom.uniform(5, "buildings/height", ids[10:20]), whole[10:20])
    assert not np.array_equal(srandom.uniform(6, "buildings/height", ids), whole)
    assert not np.array_equal(srandom.uniform(5, "buildings/roof", ids), whole)
    assert np.all((whole >= 0.0) & (whole < 1.0)) and len(set(whole.tolist())) == 50
    assert srandom.uniform(5, "k", []).shape == (0,)


@pytest.mark.parametrize("seed", [0, 1, 2**63, M])
def test_uniform_known_values(seed):
    got = srandom.uniform(seed, "lots/split", [0, 1, 2])
    assert got.tolist() == [ref_uniform(seed, "lots/split", i) for i in (0, 1, 2)]


def test_scalars_and_plain_lists_wrap_without_warnings():
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # an overflow warning would be a line on the user's stderr
        assert int(srandom.splitmix64(M)) == ref_splitmix64(M)
        assert int(srandom.splitmix64(np.uint64(M - 3))) == ref_splitmix64(M - 3)
        assert int(srandom.mix64(np.uint64(M), np.uint64(M))) == ref_splitmix64(M ^ (M * G & M))
        assert int(srandom.mix64(M, 3)) == ref_splitmix64(M ^ (3 * G & M))
        assert float(srandom.hash01(M, M)) == (ref_splitmix64(M ^ (M * G & M)) >> 11) / 2.0**53
    # plain Python ints and signed arrays are taken as uint64, not promoted to float
    assert [int(v) for v in srandom.splitmix64([0, 1, 2])] == [ref_splitmix64(i) for i in (0, 1, 2)]
    signed = srandom.splitmix64(np.array([5, 6], np.int64))
    assert signed.dtype == np.uint64 and [int(v) for v in signed] == [ref_splitmix64(5), ref_splitmix64(6)]
