"""The city plan: what a configuration's ``<city>`` element says.

The engine only carries the plan to the nodes; it gives no meaning to
district or land-use rules.  Every value is kept as the string the file holds
(plus ``where``, the file and line it came from) and the nodes that read a
rule check and convert it, so their errors can name that line.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["MapSpec", "Rule", "CityPlan"]


@dataclass(frozen=True)
class MapSpec:
    """An input file of the plan: an image map, an OSM file, an OBJ file ...

    Attributes
    ----------
    kind : str
        ``district``, ``landuse``, ``height``, ``osm``, ``roads``, ``obj`` ...
    src : pathlib.Path
        Absolute path of the file.
    attrs : dict of str to str
        The element's other attributes (``min``, ``max`` ...).
    where : str
        ``file:line`` of the element, for error messages.
    """

    kind: str
    src: Path
    attrs: dict = field(default_factory=dict)
    where: str = ""


@dataclass(frozen=True)
class Rule:
    """One rule element of the plan (``<district .../>``, ``<landuse .../>``)."""

    tag: str
    attrs: dict
    where: str = ""

    def get(self, name: str, default: str | None = None) -> str | None:
        """The attribute ``name`` as written, or ``default``."""
        return self.attrs.get(name, default)


@dataclass
class CityPlan:
    """The city plan.

    Attributes
    ----------
    name : str
        Name of the city.
    size : tuple of float
        Width and height of the city extent (m); the extent is
        ``(0, 0, width, height)`` with y pointing north.
    origin : tuple of float
        Latitude and longitude (deg, WGS84) of the planar point (0, 0).
    maps : dict of str to MapSpec
        Input files by kind.
    rules : list of Rule
        District, land-use and other rules in file order.
    attrs : dict of str to str
        Any other attributes of ``<city>``.
    where : str
        ``file:line`` of the ``<city>`` element.
    """

    name: str = "city"
    size: tuple[float, float] = (2000.0, 2000.0)
    origin: tuple[float, float] = (41.9794, 2.8214)  # Girona, where skylineEngine was made
    maps: dict[str, MapSpec] = field(default_factory=dict)
    rules: list[Rule] = field(default_factory=list)
    attrs: dict[str, str] = field(default_factory=dict)
    where: str = ""

    def rules_of(self, tag: str) -> list[Rule]:
        """The rules with element name ``tag``, in file order."""
        return [r for r in self.rules if r.tag == tag]

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """``(xmin, ymin, xmax, ymax)`` of the city (m)."""
        return (0.0, 0.0, float(self.size[0]), float(self.size[1]))
