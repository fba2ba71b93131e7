"""sengine's built-in node library, loaded by path as the package ``sengine_nodes``.

One module per family (the paper's modules): districts and patterns, minor
roads, OSM import and clean-up, blocks, lots, parks, buildings, filters,
statistics and exporters.  Importing the package registers every node.
"""

import importlib as _importlib
import pkgutil as _pkgutil

for _info in sorted(_pkgutil.iter_modules(__path__), key=lambda m: m.name):
    if not _info.name.startswith("_"):
        _importlib.import_module(f"{__name__}.{_info.name}")
