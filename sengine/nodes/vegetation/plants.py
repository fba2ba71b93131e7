"""``I(category, type, instance)``: which plant stands at a point (Ulmer et al. §2.2).

"Each tree type is classified into three different ages (young, medium and
adult age).  And for each of these categories, different appearances of the
trees are stored ...  we use I(category,type,instance) to place the tree
models.  For example, I(birch,adult,rand(7)) selects randomly one of the
first 7 instances of adult birches."  A zone's palette names the categories
it may hold (``"plane,lime"`` for an avenue); each point draws a category
from it, an age class by the zone's age shares, and an instance number below
``instances``; the three come from one hash of (seed, point key), so a point
keeps its plant whatever else is placed.

:data:`PLANTS` holds each category's form (``broad``: a round crown on a
trunk; ``conifer``: a cone) and its adult height and crown diameter
(typical European park and street trees: London plane 25-30 m, small-leaved
lime 20-25 m, pedunculate oak 20-25 m, silver birch 15-20 m, Scots pine
15-25 m, Norway maple 15-20 m, cherry 6-10 m).  Age classes scale the size
(young 0.35, medium 0.65, adult 1.0) and the instance varies it by +-15 %.

References
----------
.. [1] A. Ulmer, J. Halatsch, A. Kunze, P. Müller and L. Van Gool, "Procedural design
   of urban open spaces", Proceedings of the 25th eCAADe Conference, Frankfurt am
   Main, pp. 351-358, 2007 (paper 001 in shared/papers).
"""

from __future__ import annotations

import numpy as np

from sengine.errors import ParameterError
from sengine.random import hash01

__all__ = ["PLANTS", "AGES", "AGE_SCALE", "parse_palette", "choose_plants"]

#: category -> (form, adult height m, adult crown diameter m)
PLANTS: dict[str, tuple[str, float, float]] = {
    "plane": ("broad", 26.0, 16.0),
    "lime": ("broad", 22.0, 12.0),
    "oak": ("broad", 22.0, 16.0),
    "maple": ("broad", 17.0, 11.0),
    "birch": ("broad", 17.0, 7.0),
    "cherry": ("broad", 8.0, 6.0),
    "pine": ("conifer", 20.0, 7.0),
    "spruce": ("conifer", 24.0, 6.0),
}
#: The age classes of I(category, type, instance).
AGES = ("young", "medium", "adult")
AGE_SCALE = {"young": 0.35, "medium": 0.65, "adult": 1.0}


def parse_palette(text: str, where: str = "") -> tuple[str, ...]:
    """``"plane,lime"`` -> ``("plane", "lime")``; a name not in :data:`PLANTS` is a ParameterError."""
    names = tuple(t.strip().lower() for t in str(text).split(",") if t.strip())
    bad = [t for t in names if t not in PLANTS]
    if bad or not names:
        raise ParameterError(
            f"plant {bad[0] if bad else text!r} is not one of {', '.join(PLANTS)}", where=where or None
        )
    return names


def choose_plants(
    key: np.ndarray, palette: tuple[str, ...], ages=(0.2, 0.3, 0.5), instances: int = 7
) -> dict[str, np.ndarray]:
    """``I(category, type, instance)`` and the size of each point's plant.

    Parameters
    ----------
    key : numpy.ndarray of uint64
        One well-mixed key per point (e.g. :func:`sengine.random.mix64` of the
        seed and the point's zone and rank).
    palette : tuple of str
        Categories the zone may hold, drawn with equal chance.
    ages : tuple of float
        Shares of young, medium and adult plants.
    instances : int
        Appearances per category and age (``rand(instances)``).

    Returns
    -------
    dict of numpy.ndarray
        ``category``, ``type`` (age class), ``instance``, ``height`` (m),
        ``crown`` (diameter, m) and ``form`` (broad / conifer).
    """
    key = np.asarray(key, np.uint64)
    u = [hash01(key, np.uint64(j)) for j in range(3)]
    cats = np.array(palette)
    ci = np.minimum((u[0] * len(cats)).astype(np.int64), len(cats) - 1)
    cat = cats[ci]
    cum = np.cumsum(np.asarray(ages, np.float64) / max(float(np.sum(ages)), 1e-12))
    age_i = np.minimum(np.searchsorted(cum, u[1], side="right"), 2)
    age = np.array(AGES)[age_i]
    inst = np.minimum((u[2] * instances).astype(np.int64), instances - 1)
    table = {c: PLANTS[c] for c in palette}
    h_adult = np.array([table[c][1] for c in palette])
    c_adult = np.array([table[c][2] for c in palette])
    scale = np.array([AGE_SCALE[a] for a in AGES])[age_i] * (0.85 + 0.3 * inst / max(instances - 1, 1))
    return {
        "category": cat.astype(object),
        "type": age.astype(object),
        "instance": inst,
        "height": np.round(h_adult[ci] * scale, 2),
        "crown": np.round(c_adult[ci] * scale, 2),
        "form": np.array([table[c][0] for c in palette], dtype=object)[ci],
    }
