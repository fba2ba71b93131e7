"""OpenStreetMap import: the streaming reader and the ``osm.read`` node (skylineEngine 002 §5.2)."""
