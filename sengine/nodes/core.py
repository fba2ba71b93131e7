"""Plumbing nodes with no city knowledge.

``null`` is the pass-through node of skylineEngine §5.1: in a load-map
network the map already holds the street division, so ``minorRoads`` only
passes the roads on.

References
----------
.. [1] R. Ridorsa and G. Patow, "skylineEngine: an urban procedural modelling system",
   technical report, Geometry and Graphics Group, Universitat de Girona, 2011
   (the specification: paper 002 in shared/papers).
"""

from __future__ import annotations

from sengine import Layer, Port, SENode, register


@register
class Null(SENode):
    """Pass the input layer through unchanged."""

    name = "null"
    inputs = {"input": Port("any", "any layer")}
    outputs = {"output": Port("any", "the same layer")}
    params = {}

    def run(self, *, input: Layer) -> dict[str, Layer]:
        return {"output": input}
