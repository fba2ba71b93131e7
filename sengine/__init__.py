"""sengine: a procedural city engine in the line of skylineEngine.

A city is a DAG of registered nodes wired by an XML network file; geometry
streams between them as :class:`~sengine.layer.Layer` batches.

References
----------
.. [1] R. Ridorsa and G. Patow, "skylineEngine: an urban procedural modelling system",
   technical report, Geometry and Graphics Group, Universitat de Girona, 2011
   (the specification: paper 002 in shared/papers).
"""

__version__ = "0.1.0"

from .errors import SEngineError  # noqa: E402
from .layer import Layer  # noqa: E402
from .node import Context, NodeResult, Param, Port, SENode  # noqa: E402
from .plan import CityPlan, MapSpec, Rule  # noqa: E402
from .registry import register  # noqa: E402

__all__ = [
    "Layer",
    "SENode",
    "NodeResult",
    "Param",
    "Port",
    "Context",
    "CityPlan",
    "MapSpec",
    "Rule",
    "register",
    "SEngineError",
    "load",
    "__version__",
]


def load(path, **overrides):
    """Read a configuration file and return its :class:`~sengine.network.Network`."""
    from .xmlconfig import load_config

    return load_config(path, **overrides)
