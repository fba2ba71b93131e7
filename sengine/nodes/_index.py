"""What each module of the built-in node library registers, for :func:`sengine.registry.declare_lazy`.

Made by :func:`sengine.registry.write_index`::

    python -c "from sengine.registry import write_index; write_index('sengine.nodes')"

``tests/test_registry_lazy.py`` fails when it is out of date.  A stale index
is slower, not wrong: a name it lacks makes the registry import every module
of the library.
"""

INDEX: dict[str, dict[str, list[str]]] = {
    "node": {
        "blocks.circuits": ["sengine.nodes.blocks.circuits"],
        "blocks.grain": ["sengine.nodes.blocks.grain"],
        "blocks.landuse": ["sengine.nodes.blocks.landuse"],
        "buildings.check": ["sengine.nodes.buildings.regulation"],
        "buildings.context": ["sengine.nodes.buildings.context"],
        "buildings.existing": ["sengine.nodes.buildings.existing"],
        "buildings.extrude": ["sengine.nodes.buildings.extrude"],
        "buildings.far": ["sengine.nodes.buildings.massing"],
        "buildings.massing": ["sengine.nodes.buildings.massing"],
        "export.city": ["sengine.nodes.export.city"],
        "filter.area": ["sengine.nodes.filters"],
        "lots.district": ["sengine.nodes.lots.nodes"],
        "lots.fields": ["sengine.nodes.lots.fields"],
        "lots.manhattan": ["sengine.nodes.lots.nodes"],
        "lots.paris": ["sengine.nodes.lots.nodes"],
        "lots.partition": ["sengine.nodes.lots.partition"],
        "lots.recursive": ["sengine.nodes.lots.nodes"],
        "lots.skeleton": ["sengine.nodes.lots.nodes"],
        "maps.file": ["sengine.nodes.maps"],
        "maps.image": ["sengine.nodes.maps"],
        "null": ["sengine.nodes.core"],
        "obj.lots": ["sengine.nodes.roads.objimport"],
        "obj.roads": ["sengine.nodes.roads.objimport"],
        "osm.read": ["sengine.nodes.osm.read"],
        "parks.block": ["sengine.nodes.parks.block"],
        "parks.district": ["sengine.nodes.parks.district"],
        "parks.lot": ["sengine.nodes.parks.lot"],
        "parks.patio": ["sengine.nodes.parks.patio"],
        "plan.rules": ["sengine.nodes.maps"],
        "roads.bridges": ["sengine.nodes.roads.bridges"],
        "roads.clean": ["sengine.nodes.roads.clean"],
        "roads.districts": ["sengine.nodes.roads.districts"],
        "roads.image": ["sengine.nodes.roads.roadimage"],
        "roads.minor": ["sengine.nodes.roads.minor"],
        "stats.planning": ["sengine.nodes.stats"],
        "stats.shape": ["sengine.nodes.stats"],
        "vegetation.trees": ["sengine.nodes.vegetation.trees"],
        "water.landuse": ["sengine.nodes.water"],
    },
    "network": {
        "loadmap": ["sengine.nodes.standard"],
        "pattern": ["sengine.nodes.standard"],
        "std": ["sengine.nodes.standard"],
    },
    "rule": {
        "district": [
            "sengine.nodes.buildings.regulation",
            "sengine.nodes.buildings.rules",
            "sengine.nodes.lots.nodes",
            "sengine.nodes.roads.districts",
        ],
        "landuse": ["sengine.nodes.buildings.rules", "sengine.nodes.roads.districts"],
    },
    "kind": {
        "areas": ["sengine.nodes.kinds"],
        "blocks": ["sengine.nodes.kinds"],
        "buildings": ["sengine.nodes.kinds"],
        "file": ["sengine.nodes.kinds"],
        "graph": ["sengine.nodes.kinds"],
        "lots": ["sengine.nodes.kinds"],
        "outline": ["sengine.nodes.kinds"],
        "parks": ["sengine.nodes.kinds"],
        "polygons": ["sengine.nodes.kinds"],
        "raster": ["sengine.nodes.kinds"],
        "roads": ["sengine.nodes.kinds"],
        "rules": ["sengine.nodes.kinds"],
        "vegetation": ["sengine.nodes.kinds"],
    },
    "map_kind": {
        "district": ["sengine.nodes.maps"],
        "height": ["sengine.nodes.maps"],
        "landuse": ["sengine.nodes.maps"],
        "obj": ["sengine.nodes.maps"],
        "osm": ["sengine.nodes.maps"],
        "roads": ["sengine.nodes.maps"],
    },
    "source": {"file": ["sengine.nodes.maps"], "raster": ["sengine.nodes.maps"], "rules": ["sengine.nodes.maps"]},
    "format": {
        "cityjson": ["sengine.nodes.export.city"],
        "geojson": ["sengine.nodes.export.city"],
        "glb": ["sengine.nodes.export.city"],
        "gpkg": ["sengine.nodes.export.city"],
        "html": ["sengine.nodes.export.city"],
        "obj": ["sengine.nodes.export.city"],
        "osm": ["sengine.nodes.export.city"],
        "parquet": ["sengine.nodes.export.city"],
        "png": ["sengine.nodes.export.city"],
    },
}
