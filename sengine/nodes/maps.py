"""The plan's inputs as nodes: image maps, map files and rules on declared ports.

skylineEngine draws a city from a few images -- a district map, a land-use
map, a height map (paper 002 §5.2, Figs. 1, 2, 12) -- and a few rules per
district.  Here each of them is a *source node* whose output port carries
it, so the network graph shows every input of a city and no node reads the
configuration behind the executor's back:

============== ============= ============ ===========================================
node type      port kind     node id      made for
============== ============= ============ ===========================================
``maps.image`` ``raster``    ``<k>Map``   ``<map kind="k">`` of an image kind
                                          (district, landuse, height, roads)
``maps.file``  ``file``      ``<k>Map``   ``<map kind="k">`` of a file kind (osm, obj)
``plan.rules`` ``rules``     ``<t>Rules`` the ``<t>`` rules (``district``, ``landuse``)
============== ============= ============ ===========================================

When a configuration is loaded, :meth:`sengine.network.Network.wire_plan`
adds one such node per ``<map>`` and per rule tag some node asks for, and
connects it to every input port named ``<k>_map`` or ``<t>_rules``.  A
``raster`` layer is one feature, the city extent, with the decoded image in
``meta["image"]`` (a :class:`sengine.geom.raster.ImageMap`); a ``rules``
layer has one row per rule element, in file order, a column per attribute
(``None`` where a rule leaves it out) and ``where``, the file and line.

References
----------
.. [1] R. Ridorsa and G. Patow, "skylineEngine: an urban procedural modelling system",
   technical report, Geometry and Graphics Group, Universitat de Girona, 2011
   (the specification: paper 002 in shared/papers).
"""

from __future__ import annotations

import logging
import stat
from pathlib import Path
from typing import Any

import numpy as np
import shapely

from sengine import CityPlan, Layer, NodeResult, Param, Port, Rule, SENode, register
from sengine.errors import ConfigError, InputDataError
from sengine.geom.crs import local_crs
from sengine.geom.raster import ImageMap, parse_colour, read_map
from sengine.registry import declare_map_kind

__all__ = [
    "IMAGE_KINDS",
    "FILE_KINDS",
    "plan_meta",
    "rules_of",
    "rules_layer",
    "image_of",
    "plan_inputs",
    "MapsImage",
    "MapsFile",
    "PlanRules",
]

log = logging.getLogger(__name__)

IMAGE_KINDS = {
    "district": "district map: one colour per <district> rule",
    "landuse": "land-use map: one colour per <landuse> rule (water, parks ... are cut out of the city)",
    "height": "height map: grey levels from min (black) to max (white) metres",
    "roads": "road map: streets drawn in one colour, traced into centre lines",
}
FILE_KINDS = {
    "osm": "OpenStreetMap extract (.osm, .osm.bz2, .osm.pbf)",
    "obj": "Wavefront OBJ file of street lines or lot polygons",
}
MAX_HEIGHT = 1000.0  # m; the tallest building stands 828 m


def plan_meta(plan: CityPlan) -> dict:
    """Layer meta of a synthetic city: its planar CRS (local transverse Mercator at the origin), origin and extent."""
    return {"crs": local_crs(plan.origin), "origin": tuple(plan.origin), "extent": tuple(plan.extent)}


def rules_layer(rules: list[Rule], meta: dict | None = None) -> Layer:
    """The ``rules`` layer of a list of rule elements (one row each; see the module doc)."""
    names: list[str] = []
    for rule in rules:
        names += [k for k in rule.attrs if k not in names]
    cols: dict[str, Any] = {}
    for name in names:
        col = np.empty(len(rules), dtype=object)
        col[:] = [rule.attrs.get(name) for rule in rules]
        cols[name] = col
    where = np.array([rule.where for rule in rules], dtype=str) if rules else np.empty(0, "<U1")
    tag = rules[0].tag if rules else ""
    return Layer.from_geoms([None] * len(rules), meta={**(meta or {}), "tag": tag}, where=where, **cols)


def rules_of(layer: Layer | None, tag: str | None = None) -> list[Rule]:
    """The rule elements a ``rules`` layer holds, in file order (``[]`` for ``None``)."""
    if layer is None:
        return []
    tag = tag or layer.meta.get("tag", "")
    names = [k for k in layer.columns if k != "where"]
    where = layer.get("where", np.full(len(layer), "", dtype=object))
    out = []
    for i in range(len(layer)):
        attrs = {k: str(layer[k][i]) for k in names if layer[k][i] is not None}
        out.append(Rule(tag, attrs, str(where[i])))
    return out


def image_of(layer: Layer | None) -> ImageMap | None:
    """The decoded image a ``raster`` layer carries (``None`` for ``None`` or an empty layer: no map)."""
    if layer is None or not len(layer):
        return None
    return layer.meta["image"]


def plan_inputs(plan: CityPlan, node: type[SENode] | SENode, *, base_dir: Path | None = None) -> dict[str, Layer]:
    """The layers the plan's source nodes hand to ``node``'s input ports, by port name.

    What a loaded configuration wires up (:meth:`sengine.network.Network.wire_plan`),
    for scripts and tests that run one node by hand:
    ``node.run(areas=..., **plan_inputs(plan, node))``.  Ports the plan has
    nothing for are left out.
    """
    from sengine.node import Context, NodeResult
    from sengine.registry import source_classes

    sources = source_classes()
    out: dict[str, Layer] = {}
    for port_name, port in node.inputs.items():
        cls = sources.get(port.kind)
        key, _, suffix = port_name.rpartition("_")
        made = cls.plan_source(key, plan) if cls is not None and key else None
        if made is None:
            continue
        params, where = made
        src = cls(f"{key}{suffix.capitalize()}", params, Context(plan=plan, base_dir=base_dir), where=where or None)
        out[port_name] = next(iter(NodeResult.of(src, src.run()).layers.values()))
    return out


@register
class MapsImage(SENode):
    """An image map of the plan (``<map kind=... src=...>``), read and placed on the city extent.

    The image is decoded once, here: colour (RGB) for district, land-use and
    road maps, one grey channel at its bit depth for height maps.  A missing,
    unreadable or over-large file, or one whose width / height ratio is not
    the city's, is an error naming the ``<map>`` line.
    """

    name = "maps.image"
    inputs = {}
    outputs = {"map": Port("raster", "the decoded image on the city extent (meta 'image')")}
    params = {
        "kind": Param("str", None, choices=tuple(IMAGE_KINDS), doc="what the image is a map of"),
        "src": Param("path", None, doc="the image file (PNG, JPEG, TIFF ...)"),
        "min": Param("float", -1.0, min=-1.0, max=MAX_HEIGHT, unit="m", doc="height maps: height of black; -1 unset"),
        "max": Param("float", -1.0, min=-1.0, max=MAX_HEIGHT, unit="m", doc="height maps: height of white; -1 unset"),
        "tolerance": Param(
            "float",
            -1.0,
            min=-1.0,
            max=442.0,
            unit="1",
            doc=(
                "largest RGB distance from a legend colour (road maps: from the streets' colour); -1: 0 for"
                " lossless files, 60 for lossy ones (road maps: roads.image's own tolerance)"
            ),
        ),
        "color": Param("str", "", doc="road maps: colour of the streets (empty: the road node's own)"),
    }
    source_for = "raster"

    @classmethod
    def plan_source(cls, key: str, plan: Any) -> tuple[dict[str, Any], str] | None:
        spec = getattr(plan, "maps", {}).get(key)
        if spec is None or key not in IMAGE_KINDS:
            return None
        return {"kind": key, "src": str(spec.src), **spec.attrs}, spec.where

    def check_height(self) -> tuple[float, float]:
        """``(min, max)`` of a height map; ConfigError unless ``0 <= min <= max``."""
        lo, hi = self.p["min"], self.p["max"]
        if not (0 <= lo <= hi):
            given = ", ".join(f"{k}={self.p[k]:g}" for k in ("min", "max") if self.p[k] >= 0) or "neither"
            raise ConfigError(
                f"height map needs min and max in metres with 0 <= min <= max <= {MAX_HEIGHT:g} (given: {given})",
                where=self.where,
            )
        return lo, hi

    def run(self):
        if self.p.kind == "height":
            self.check_height()
        if self.p.color:
            parse_colour(self.p.color, where=self.where)
        plan = self.context.plan if self.context.plan is not None else CityPlan()
        src = Path(self.p.src)
        if not src.is_absolute() and self.context.base_dir is not None:
            src = Path(self.context.base_dir) / src
        image = read_map(src, plan.extent, where=self.where, colour=self.p.kind != "height")
        lay = Layer.from_geoms(
            [shapely.box(*plan.extent)],
            meta={**plan_meta(plan), "image": image},
            kind=np.array([self.p.kind]),
            src=np.array([str(src)]),
            min=np.array([self.p["min"]]),
            max=np.array([self.p["max"]]),
            tolerance=np.array([self.p.tolerance]),
            color=np.array([self.p.color]),
        )
        rows, cols = image.shape
        return NodeResult({"map": lay}, {"pixels": int(rows * cols), "width_px": int(cols), "height_px": int(rows)})


@register
class MapsFile(SENode):
    """A map file of the plan (``<map kind="osm"|"obj" src=...>``): checked here, read by its consumer.

    The file must exist and be a regular, non-empty file; its reader (``osm.read``,
    ``obj.roads`` ...) parses it.
    """

    name = "maps.file"
    inputs = {}
    outputs = {"file": Port("file", "the path of the file (column src)")}
    params = {
        "kind": Param("str", None, choices=tuple(FILE_KINDS), doc="what the file is"),
        "src": Param("path", None, doc="the file"),
    }
    source_for = "file"

    @classmethod
    def plan_source(cls, key: str, plan: Any) -> tuple[dict[str, Any], str] | None:
        spec = getattr(plan, "maps", {}).get(key)
        if spec is None or key not in FILE_KINDS:
            return None
        return {"kind": key, "src": str(spec.src), **spec.attrs}, spec.where

    def run(self):
        src = Path(self.p.src)
        if not src.is_absolute() and self.context.base_dir is not None:
            src = Path(self.context.base_dir) / src
        size = check_regular_file(src, f"{self.p.kind} file", self.where)
        plan = self.context.plan if self.context.plan is not None else CityPlan()
        meta = {**plan_meta(plan), "where": self.where.split(": node ")[0]}
        lay = Layer.from_geoms([None], meta=meta, kind=np.array([self.p.kind]), src=np.array([str(src)]))
        return NodeResult({"file": lay}, {"bytes": size})


def check_regular_file(path: Path, what: str, where: str | None) -> int:
    """The size of ``path`` (bytes); InputDataError unless it is a non-empty regular file."""
    try:
        st = path.stat()
    except FileNotFoundError:
        raise InputDataError(f"{what} {str(path)!r} does not exist", where=where) from None
    except OSError as exc:
        raise InputDataError(f"{what} {str(path)!r}: cannot read ({exc.strerror})", where=where) from None
    if stat.S_ISDIR(st.st_mode):
        raise InputDataError(f"{what} {str(path)!r} is a folder, not a file", where=where)
    if not stat.S_ISREG(st.st_mode):
        raise InputDataError(f"{what} {str(path)!r} is not a regular file (a pipe or device?)", where=where)
    if st.st_size == 0:
        raise InputDataError(f"{what} {str(path)!r} is empty", where=where)
    return int(st.st_size)


@register
class PlanRules(SENode):
    """The plan's rule elements of one tag (``<district>``, ``<landuse>``) as a table, one row per rule.

    The attributes were checked against their declarations when the
    configuration was read (:func:`sengine.registry.declare_rule`); the
    layer's meta holds the city's CRS, origin and extent.
    """

    name = "plan.rules"
    inputs = {}
    outputs = {"rules": Port("rules", "one row per rule, a column per attribute, 'where' the file and line")}
    params = {"tag": Param("str", None, doc="the rule element's name: district, landuse ...")}
    source_for = "rules"

    @classmethod
    def plan_source(cls, key: str, plan: Any) -> tuple[dict[str, Any], str] | None:
        return {"tag": key}, getattr(plan, "where", "") or ""

    def run(self):
        plan = self.context.plan if self.context.plan is not None else CityPlan()
        rules = plan.rules_of(self.p.tag)
        return NodeResult(
            {"rules": rules_layer(rules, plan_meta(plan)).with_meta(tag=self.p.tag)}, {"rules": len(rules)}
        )


for _kind, _doc in IMAGE_KINDS.items():
    declare_map_kind(_kind, "raster", _doc)
for _kind, _doc in FILE_KINDS.items():
    declare_map_kind(_kind, "file", _doc)
