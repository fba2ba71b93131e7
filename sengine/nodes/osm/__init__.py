"""OpenStreetMap import: the streaming reader and the ``osm.read`` node (skylineEngine 002 §5.2).

References
----------
.. [1] R. Ridorsa and G. Patow, "skylineEngine: an urban procedural modelling system",
   technical report, Geometry and Graphics Group, Universitat de Girona, 2011
   (the specification: paper 002 in shared/papers).
"""
