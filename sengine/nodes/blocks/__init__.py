"""Blocks: minimal circuits of the street graph, sidewalks, and land use cut out (skylineEngine 002 §5.4)."""
