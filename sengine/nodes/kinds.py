"""The layer kinds of the node library: the columns each kind carries, with their dtypes.

A port's kind (``Port("lots", ...)``) is a promise about the layer on it:
the *required* columns below are on every non-empty layer of the kind, with
a numpy dtype of the listed kinds (``i`` integer, ``f`` float, ``b`` bool,
``U`` / ``O`` text as fixed-width or object strings).  Other columns may
ride along.  ``sengine run --debug`` checks every layer a node hands on
(:func:`sengine.registry.check_kind`), and so do the tests on every demo.

A plugin declares its own kinds, or more optional columns of these, with
:func:`sengine.registry.declare_kind`.
"""

from __future__ import annotations

from sengine.registry import declare_kind

__all__ = ["KINDS"]

INT, FLOAT, BOOL, TEXT = "iu", "f", "b", "UO"

KINDS: dict[str, tuple[str, dict[str, tuple[str, bool, str]]]] = {
    "roads": (
        "street centre lines between junctions (m, planar)",
        {
            "class": (TEXT, True, "road class: OSM highway value, major, minor, boundary"),
            "major": (BOOL, True, "counts as a major road"),
            "width": (FLOAT, True, "street width between block fronts (m)"),
            "u": (INT, False, "start junction (index into meta 'nodes')"),
            "v": (INT, False, "end junction (index into meta 'nodes')"),
            "layer": (INT, False, "OSM layer: ways on different layers cross without meeting"),
            "bridge": (BOOL, False, "a bridge: meets other ways only at shared nodes"),
            "tunnel": (BOOL, False, "a tunnel: meets other ways only at shared nodes"),
            "oneway": (BOOL, False, "OSM oneway"),
            "district": (INT, False, "district index (-1 none)"),
            "osm_id": (INT, False, "OSM way id"),
            "name": (TEXT, False, "street name"),
        },
    ),
    "areas": (
        "areas enclosed by major roads",
        {
            "district": (INT, True, "district index"),
            "name": (TEXT, False, "district name"),
            "pattern": (TEXT, False, "the district's major-road pattern"),
            "area": (FLOAT, False, "area (m2)"),
        },
    ),
    "outline": ("the buildable city: extent minus land-use cut-outs", {"kind": (TEXT, False, "'outline'")}),
    "blocks": (
        "city blocks: faces of the street graph, shrunk for streets and sidewalks",
        {
            "district": (INT, True, "district index (-1 none)"),
            "face": (INT, False, "the street-graph face the block was shrunk from"),
            "half_width": (FLOAT, False, "mean half-width of the streets around the face (m)"),
            "footprint": (FLOAT, False, "built footprint (m2, stats.planning)"),
            "floor_area": (FLOAT, False, "gross floor area (m2, stats.planning)"),
            "far": (FLOAT, False, "floor-area ratio (1, stats.planning)"),
            "coverage": (FLOAT, False, "footprint / site area (1, stats.planning)"),
        },
    ),
    "polygons": (
        "plain polygons with a kind: streets, sidewalks, water, medians ...",
        {
            "kind": (TEXT, True, "street, sidewalk, water, median, island ..."),
            "name": (TEXT, False, "name from the map"),
            "osm_id": (INT, False, "OSM id"),
        },
    ),
    "parks": (
        "parks at district, block or lot level, and patio zones",
        {
            "level": (TEXT, True, "district, block, lot or patio"),
            "district": (INT, False, "district index (-1 none)"),
            "area": (FLOAT, False, "area (m2)"),
            "kind": (TEXT, False, "park, garden ..."),
            "name": (TEXT, False, "name from the map"),
            "osm_id": (INT, False, "OSM id"),
        },
    ),
    "vegetation": (
        "trees: one point each, with the plant I(category, type, instance) of Ulmer et al. 2007",
        {
            "zone": (TEXT, True, "avenue, district, block, lot, patio or region"),
            "category": (TEXT, True, "plant category: plane, lime, oak, birch, pine ..."),
            "type": (TEXT, True, "age class: young, medium, adult"),
            "instance": (INT, True, "appearance number, below the node's instances"),
            "height": (FLOAT, True, "height (m)"),
            "crown": (FLOAT, True, "crown diameter (m)"),
            "form": (TEXT, False, "broad or conifer"),
            "park": (INT, False, "id of the tree's park or region (-1 none)"),
            "district": (INT, False, "district index (-1 none)"),
        },
    ),
    "lots": (
        "lots: the parcels buildings stand on",
        {
            "block": (INT, True, "id of the block the lot was cut from (-1 none)"),
            "district": (INT, True, "district index (-1 none)"),
            "corner": (BOOL, True, "a corner lot (fronts two streets)"),
            "frontage": (FLOAT, True, "length along the street (m; NaN unknown)"),
            "street_edges": (INT, True, "how many of its edges face a street"),
            "method": (TEXT, True, "the subdivision that made it: manhattan, paris, recursive, obj ..."),
            "front_angle": (FLOAT, False, "direction of the street front (rad)"),
            "inner": (BOOL, False, "an inner lot without street access (Paris courtyards)"),
            "footprint": (FLOAT, False, "built footprint (m2, stats.planning)"),
            "floor_area": (FLOAT, False, "gross floor area (m2, stats.planning)"),
            "far": (FLOAT, False, "floor-area ratio (1, stats.planning)"),
            "coverage": (FLOAT, False, "footprint / lot area (1, stats.planning)"),
        },
    ),
    "buildings": (
        "building footprints with height",
        {
            "height": (FLOAT, True, "height (m)"),
            "floors": (INT, True, "storeys"),
            "roof": (TEXT, True, "roof shape: flat ..."),
            "lot": (INT, True, "id of the lot it stands on (-1 none)"),
            "district": (INT, True, "district index (-1 none)"),
            "source": (TEXT, False, "generated or map"),
            "height_source": (TEXT, False, "where the height came from"),
            "name": (TEXT, False, "name from the map"),
            "osm_id": (INT, False, "OSM id"),
        },
    ),
    "raster": (
        "an image map of the plan on the city extent: one feature, the decoded image in meta 'image'",
        {
            "kind": (TEXT, True, "district, landuse, height, roads"),
            "src": (TEXT, True, "the image file"),
            "min": (FLOAT, True, "height maps: height of black (m; -1 unset)"),
            "max": (FLOAT, True, "height maps: height of white (m; -1 unset)"),
            "tolerance": (FLOAT, True, "largest RGB distance to a legend colour (-1: by file type)"),
            "color": (TEXT, True, "road maps: street colour ('' unset)"),
        },
    ),
    "file": (
        "a map file of the plan (OSM, OBJ): one feature without geometry",
        {"kind": (TEXT, True, "osm, obj"), "src": (TEXT, True, "the file")},
    ),
    "rules": (
        "rule elements of the plan, one row each; a column per attribute (None where left out)",
        {"where": (TEXT, True, "file and line of the element")},
    ),
    "graph": (
        "a plane straight-segment graph: one segment per feature, traced faces in meta 'faces'",
        {
            "u": (INT, True, "start node (index into meta 'xy')"),
            "v": (INT, True, "end node (index into meta 'xy')"),
            "row": (INT, True, "the street segment it lies on"),
        },
    ),
}

for _kind, (_doc, _columns) in KINDS.items():
    declare_kind(_kind, _columns, doc=_doc)
