"""sengine's built-in node library: the city (roads, blocks, lots, parks, buildings, exporters).

It is the first plugin of the ``sengine.nodes`` entry-point group, loaded the
way a user's node package is.  One sub-package or module per family (the
paper's modules): ``roads`` (districts, patterns, minor roads, clean-up, road
images, OBJ), ``osm``, ``blocks``, ``lots``, ``parks``, ``buildings``,
``filters``, ``stats`` and ``export`` (the city writers); ``standard`` holds
the standard networks, whose wiring lives in ``networks/``.

Importing the package imports none of them: it declares what each module
registers (:data:`sengine.nodes._index.INDEX`, made by
:func:`sengine.registry.write_index`) and the registry imports a module when
a run first asks for something of it (:func:`sengine.registry.declare_lazy`),
so a run pays for the modules, and the libraries, it uses.
"""

from sengine.registry import declare_lazy as _declare_lazy

from ._index import INDEX as _INDEX

_declare_lazy(_INDEX, package=__name__)
