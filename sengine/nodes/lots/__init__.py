"""Lots: Manhattan, Paris, recursive and per-district subdivision of blocks (skylineEngine 002 §5.5)."""
