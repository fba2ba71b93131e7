"""Layer <-> GeoJSON: the one file format the engine itself knows.

The city writers (glTF, OBJ, CityJSON, OSM XML, the PNG preview) are part of
the node library, :mod:`sengine.nodes.export`.
"""
