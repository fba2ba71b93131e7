"""What a parks node counts: the parks of its own level, not the whole stream it hands on."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from sengine import Layer

__all__ = ["CountsItsLevel"]


class CountsItsLevel:
    """Mixin of the parks nodes: ``counted`` (the run's counts line) is the parks of ``level`` they made.

    Each parks node passes the parks made upstream through on its ``parks``
    output, so that output's length is every park so far; the counts line
    and ``stats.json`` say how many this level added.
    """

    level: str = ""

    def counted(self, layers: Mapping[str, Layer]) -> int:
        parks = layers.get("parks")
        if parks is None or not len(parks) or "level" not in parks:
            return 0
        return int((np.asarray(parks["level"]).astype(str) == self.level).sum())
