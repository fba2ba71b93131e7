"""Vegetation: trees as a layer of points (Ulmer et al., "Procedural design of urban open spaces").

:mod:`.distr` is ``Distr(density, deviation)`` with a minimum spacing,
:mod:`.plants` is ``I(category, type, instance)``, :mod:`.avenue` places the
avenue zones' street trees, :mod:`.versailles` is the recursive Versailles
pattern, and :mod:`.trees` is the node ``vegetation.trees`` that fills the
zones: avenue, the parks of every level (district, block, lot, patio) and
vegetation regions.
"""

from .avenue import avenue_points, tree_lines
from .distr import distr, expected_counts, hard_core
from .plants import AGES, PLANTS, choose_plants
from .trees import VegetationTrees, place_trees
from .versailles import versailles_split

__all__ = [
    "AGES",
    "PLANTS",
    "avenue_points",
    "choose_plants",
    "distr",
    "expected_counts",
    "hard_core",
    "place_trees",
    "tree_lines",
    "versailles_split",
    "VegetationTrees",
]
