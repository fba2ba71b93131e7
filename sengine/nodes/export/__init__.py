"""The city writers: glTF, OBJ, CityJSON, OSM XML and the PNG plan, driven by the ``export.city`` node."""
