"""Street networks, the major and minor roads of skylineEngine 002 §5.3.

Districts and their patterns (grid, radial, organic), minor roads, clean-up
of real street graphs, streets from road-map images and OBJ files.

References
----------
.. [1] R. Ridorsa and G. Patow, "skylineEngine: an urban procedural modelling system",
   technical report, Geometry and Graphics Group, Universitat de Girona, 2011
   (the specification: paper 002 in shared/papers).
"""
