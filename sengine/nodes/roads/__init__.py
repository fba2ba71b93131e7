"""Street networks: districts and their patterns (grid, radial, organic), minor roads, clean-up of real
street graphs, streets from road-map images and OBJ files (skylineEngine 002 §5.3)."""
