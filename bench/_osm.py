"""The network ``sengine osm FILE`` runs, for the benchmarks: one place that knows how to load it."""

from __future__ import annotations

import tempfile
from pathlib import Path
from xml.sax.saxutils import quoteattr


def osm_network(path: Path, sets: list[str] | tuple[str, ...] = (), *, name: str | None = None):
    """The load-map network on the OSM file ``path`` (its map on the plan's port, as a config would put it)."""
    import sengine

    with tempfile.TemporaryDirectory() as tmp:
        config = Path(tmp) / "osm.xml"
        config.write_text(
            f'<sengine version="1"><city name={quoteattr(name or Path(path).stem)}>'
            f'<map kind="osm" src={quoteattr(str(Path(path).resolve()))}/></city>'
            '<network base="loadmap"/></sengine>'
        )
        return sengine.load(config, sets=list(sets))
