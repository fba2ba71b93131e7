"""sengine's built-in node library: the city (roads, blocks, lots, parks, buildings, exporters).

It is the first plugin of the ``sengine.nodes`` entry-point group, loaded the
way a user's node package is: importing it registers every node and every
standard network.  One sub-package or module per family (the paper's
modules): ``roads`` (districts, patterns, minor roads, clean-up, road images,
OBJ), ``osm``, ``blocks``, ``lots``, ``parks``, ``buildings``, ``filters``,
``stats`` and ``export`` (the city writers); ``standard`` holds the standard
networks, whose wiring lives in ``networks/``.
"""

import importlib as _importlib
import pkgutil as _pkgutil

for _info in sorted(_pkgutil.walk_packages(__path__, prefix=f"{__name__}."), key=lambda m: m.name):
    if not _info.name.rpartition(".")[2].startswith("_"):
        _importlib.import_module(_info.name)
