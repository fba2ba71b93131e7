"""Randomness, one way for every node: keyed by (network seed, node id, feature id).

Two forms of the same idea, both independent of how the executor batches
features, so the same seed gives the same bytes for any number of workers:

* :func:`generator` -- a :class:`numpy.random.Generator` per key, seeded
  through :class:`numpy.random.SeedSequence` (``SENode.rng`` calls it). Use it
  where an algorithm draws a varying number of values per feature.
* :func:`uniform` and :func:`mix64` -- a counter-based hash (SplitMix64 [1]_)
  giving one number per (key, counter) pair in a single vectorized call, at
  some 20 ns per number. Use it for one or a few draws per feature over
  whole arrays.

References
----------
.. [1] G. L. Steele Jr., D. Lea and C. H. Flood, "Fast splittable pseudorandom
   number generators", Proceedings of the 2014 ACM International Conference on
   Object Oriented Programming Systems Languages & Applications (OOPSLA '14),
   pp. 453-472, 2014. doi:10.1145/2660193.2660195
"""

from __future__ import annotations

import hashlib

import numpy as np

__all__ = ["stable_hash", "generator", "splitmix64", "mix64", "hash01", "uniform", "normal"]

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MASK = 0xFFFFFFFFFFFFFFFF


def stable_hash(text: str) -> int:
    """A 64-bit integer from a string, the same on every run and machine (BLAKE2b)."""
    return int.from_bytes(hashlib.blake2b(text.encode(), digest_size=8).digest(), "little")


def _word(k: int | str) -> int:
    return stable_hash(k) if isinstance(k, str) else int(k) & _MASK


def generator(seed: int, node_id: str, *key: int | str) -> np.random.Generator:
    """The generator of ``(seed, node_id, *key)``.

    Called with a feature id as ``key`` it gives the per-feature generator, so
    a feature's draws do not depend on which other features share its batch.

    Parameters
    ----------
    seed : int
        The network seed.
    node_id : str
        The node's id in the network.
    *key : int or str
        Feature id and any purpose labels; strings are hashed.
    """
    words = [int(seed) & _MASK, stable_hash(node_id), *(_word(k) for k in key)]
    return np.random.default_rng(np.random.SeedSequence(words))


def splitmix64(x) -> np.ndarray:
    """The SplitMix64 step over a uint64 array: add the golden gamma, then mix (wrapping)."""
    with np.errstate(over="ignore"):
        x = np.asarray(x, dtype=np.uint64) + _GOLDEN
        x = (x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        x = (x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        return x ^ (x >> np.uint64(31))


def mix64(seed, key) -> np.ndarray:
    """Well-mixed uint64 numbers from ``(seed, key)`` uint64 pairs (broadcast)."""
    with np.errstate(over="ignore"):
        return splitmix64(np.asarray(seed, np.uint64) ^ (np.asarray(key, np.uint64) * _GOLDEN))


def hash01(seed, key) -> np.ndarray:
    """Uniform numbers in ``[0, 1)`` from ``(seed, key)`` uint64 pairs (53 bits each)."""
    return (mix64(seed, key) >> np.uint64(11)).astype(np.float64) / float(1 << 53)


def uniform(seed: int, key: str, ids) -> np.ndarray:
    """One uniform number in ``[0, 1)`` per feature id, from ``(seed, key, id)``.

    The vectorized counterpart of drawing one number from
    ``generator(seed, node_id, feature_id)``: it depends on the feature's own
    id only, never on which other features share its chunk or their order.

    Parameters
    ----------
    seed : int
        The network seed.
    key : str
        Node id (and purpose, e.g. ``"buildings/height"``) separating streams.
    ids : array of int
        Feature ids.
    """
    k = splitmix64(np.array([int(seed) & _MASK], np.uint64))
    k = splitmix64(k ^ np.uint64(stable_hash(key)))
    u = splitmix64(k ^ splitmix64(np.asarray(ids, np.int64).astype(np.uint64)))
    return (u >> np.uint64(11)).astype(np.float64) * (1.0 / 9007199254740992.0)


def normal(seed: int, key: str, ids) -> np.ndarray:
    """One standard normal number per feature id, from ``(seed, key, id)`` (Box-Muller on two :func:`uniform` draws).

    Parameters
    ----------
    seed : int
        The network seed.
    key : str
        Node id and purpose, separating streams (two streams, ``key + "/u1"`` and ``key + "/u2"``, are drawn).
    ids : array of int
        Feature ids.
    """
    u1 = uniform(seed, f"{key}/u1", ids)
    u2 = uniform(seed, f"{key}/u2", ids)
    return np.sqrt(-2.0 * np.log1p(-u1)) * np.cos(2.0 * np.pi * u2)  # 1 - u1 in (0, 1]: never log(0)
