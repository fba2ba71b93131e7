"""Buildings: generated envelopes on lots and the map's own buildings (skylineEngine 002 §5.6)."""
