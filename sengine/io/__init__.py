"""Importers and exporters: glTF, OBJ, GeoJSON, OSM XML, CityJSON, PNG preview.

Exporters take :class:`~sengine.layer.Layer` objects in the planar frame and
write one file each; meshes are built in batches by :mod:`sengine.io.mesh`.
Every writer is deterministic: the same layers give byte-identical files.
"""
