"""The standard networks of skylineEngine §5.1: stdNetwork, patternNetwork, stdLoadMapNetwork.

:class:`StdNetwork` is the paper's convenience class: a network built around
the standard names ``majorRoads``, ``minorRoads``, ``blocks``, ``lots`` and
``buildings`` with a list of associations that replace the node behind a
name.  :class:`PatternNetwork` and :class:`LoadMapNetwork` derive from it and
read their wiring from ``networks/`` beside this module.  They are registered
under the names a configuration's ``<network base="...">`` uses.

References
----------
.. [1] R. Ridorsa and G. Patow, "skylineEngine: an urban procedural modelling system",
   technical report, Geometry and Graphics Group, Universitat de Girona, 2011
   (the specification: paper 002 in shared/papers).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any, ClassVar

from sengine.errors import NetworkError
from sengine.network import Network, NodeSpec
from sengine.registry import register_network
from sengine.xmlconfig import read_network_file

__all__ = ["StdNetwork", "PatternNetwork", "LoadMapNetwork", "NETWORKS_DIR"]

NETWORKS_DIR = Path(__file__).resolve().parent / "networks"


@register_network("std")
class StdNetwork(Network):
    """The standard city network of skylineEngine §5.1.

    Built around the standard names; ``associations`` (a mapping or pairs
    of standard name -> registered node type) replace the node behind a name.
    Subclasses name a wiring file in ``networks/`` as ``template``; the base
    class chains the associated names in standard order.

    Raises
    ------
    NetworkError
        When an association names a standard name the network lacks, or a
        required name (``majorRoads``, ``minorRoads``) is missing.
    """

    STANDARD: ClassVar[tuple[str, ...]] = ("majorRoads", "minorRoads", "blocks", "lots", "buildings")
    REQUIRED: ClassVar[tuple[str, ...]] = ("majorRoads", "minorRoads")
    template: ClassVar[str | None] = None

    def __init__(
        self, associations: Mapping[str, str] | Iterable[tuple[str, str]] = (), *, where: str = "", **kwargs: Any
    ):
        super().__init__(**kwargs)
        pairs = list(associations.items()) if isinstance(associations, Mapping) else list(associations)
        if self.template is not None:
            self.merge(read_network_file(NETWORKS_DIR / f"{self.template}.xml"))
            for name, type_ in pairs:
                if name not in self.specs:
                    raise NetworkError(
                        f"{type(self).__name__} has no standard name {name!r} (names: {', '.join(self.names())})",
                        where=where or None,
                    )
                self.replace(name, type_, where=where)
        else:
            unknown = [name for name, _ in pairs if name not in self.STANDARD]
            if unknown:
                raise NetworkError(
                    f"{unknown[0]!r} is not a standard name ({', '.join(self.STANDARD)})", where=where or None
                )
            given = dict(pairs)
            chain = [name for name in self.STANDARD if name in given]
            for name in chain:
                self.add(name, given[name], where=where)
            for a, b in zip(chain, chain[1:]):
                self.connect(a, b, where=where)
        missing = [name for name in self.REQUIRED if name not in self.specs]
        if missing:
            raise NetworkError(f"{type(self).__name__} needs the standard name {missing[0]!r}", where=where or None)

    @classmethod
    def from_config(cls, pairs: Iterable[tuple[str, str]], *, where: str = "", **kwargs: Any) -> StdNetwork:
        """The network a ``<network base=...>`` names.

        The plain stdNetwork takes its associations from the ``<node id type>``
        elements with standard names.
        """
        if cls.template is None:
            return cls([(i, t) for i, t in pairs if i in cls.STANDARD], where=where, **kwargs)
        return cls(where=where, **kwargs)

    def names(self) -> list[str]:
        """The standard names this network has."""
        return [n for n in self.STANDARD if n in self.specs]

    def standard(self, name: str) -> NodeSpec:
        """The node behind a standard name; raises NetworkError when absent."""
        if name not in self.STANDARD:
            raise NetworkError(f"{name!r} is not a standard name ({', '.join(self.STANDARD)})")
        if name not in self.specs:
            raise NetworkError(f"{type(self).__name__} has no node behind the standard name {name!r}")
        return self.specs[name]


@register_network("pattern")
class PatternNetwork(StdNetwork):
    """Synthetic cities from patterns: districts, major and minor roads (``networks/pattern.xml``)."""

    template = "pattern"


@register_network("loadmap")
class LoadMapNetwork(StdNetwork):
    """Cities from a map file; ``minorRoads`` is a pass-through null node (``networks/loadmap.xml``)."""

    template = "loadmap"
