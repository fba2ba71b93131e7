"""SENode: the abstract base of every node (skylineEngine §5.1).

A node is a declaration plus one method.  It declares its input and output
ports (each carrying a layer of a named *kind*), and its parameters (type,
default, inclusive bounds or choices, unit, one-line doc).  ``run`` takes the
input layers as keyword arguments named after the input ports and returns a
dict of output layers keyed by output port name.

The engine knows nothing about what the kinds mean: ``"roads"`` or
``"blocks"`` are just labels that must match between connected ports.

References
----------
.. [1] R. Ridorsa and G. Patow, "skylineEngine: an urban procedural modelling system",
   technical report, Geometry and Graphics Group, Universitat de Girona, 2011
   (the specification: paper 002 in shared/papers).
"""

from __future__ import annotations

import difflib
import inspect
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, ClassVar

import numpy as np

from .errors import NodeError, ParameterError, SEngineError
from .geom.raster import parse_colour
from .layer import Layer
from .random import generator

__all__ = ["Param", "Port", "SENode", "Context", "NodeResult"]

ANY = "any"
_TYPES = {"float": float, "int": int, "str": str, "bool": bool, "path": str, "colour": str}
_SPLIT = re.compile(r"[\s,]+")


@dataclass(frozen=True)
class Port:
    """An input or output of a node.

    Parameters
    ----------
    kind : str
        Label of the layer the port carries; ``"any"`` matches every kind.
    doc : str
        One line saying what flows through the port.
    required : bool
        Inputs only: whether the network must connect it.
    """

    kind: str
    doc: str = ""
    required: bool = True

    def accepts(self, kind: str) -> bool:
        """Whether a layer of ``kind`` may flow through this port."""
        return ANY in (self.kind, kind) or self.kind == kind


@dataclass(frozen=True)
class Param:
    """A declared, typed node parameter.

    Parameters
    ----------
    type : {"float", "int", "str", "bool", "path", "colour"}
        Python type of the value; ``path`` is a file path resolved against
        the configuration file's folder; ``colour`` is ``#rrggbb``, ``#rgb``
        or ``r g b`` (0-255), kept as written.
    default : object
        Value used when the configuration sets none; ``None`` means required.
    min, max : float, optional
        Inclusive bounds for numbers.
    choices : tuple of str, optional
        Allowed values for strings.
    unit : str
        ``m``, ``m2``, ``deg``, ``1`` ... (empty for none).
    doc : str
        One line for ``sengine nodes`` and error messages.
    count : int
        Numbers only: how many the value holds (``"800 260"`` is 2); the
        value is then a tuple and the bounds hold for each number.
    """

    type: str
    default: Any = None
    min: float | None = None
    max: float | None = None
    choices: tuple[str, ...] | None = None
    unit: str = ""
    doc: str = ""
    count: int = 1

    def __post_init__(self):
        if self.type not in _TYPES:
            raise TypeError(f"unknown parameter type {self.type!r}; expected one of {sorted(_TYPES)}")

    def coerce(self, value: Any, where: str, name: str) -> Any:
        """Return ``value`` converted to the declared type, or raise ParameterError."""
        if self.count > 1 and self.type in ("float", "int"):
            parts = _SPLIT.split(value.strip()) if isinstance(value, str) else list(value)
            parts = [p for p in parts if p != ""]
            if len(parts) != self.count:
                raise ParameterError(f"{name}={value!r} must be {self.count} numbers", where=where)
            return tuple(self._coerce_one(v, where, name) for v in parts)
        return self._coerce_one(value, where, name)

    def _coerce_one(self, value: Any, where: str, name: str) -> Any:
        unit = f" {self.unit}" if self.unit and self.unit != "1" else ""
        try:
            if self.type == "bool" and isinstance(value, str):
                low = value.strip().lower()
                if low not in ("true", "false", "1", "0", "yes", "no"):
                    raise ValueError(value)
                value = low in ("true", "1", "yes")
            elif self.type == "int" and isinstance(value, str):
                value = int(value.strip())
            elif self.type == "float" and isinstance(value, str):
                value = float(value.strip())
            elif self.type == "colour":
                parse_colour(value, where=where)
                value = str(value)
            else:
                value = _TYPES[self.type](value)
        except SEngineError as exc:  # first: InputDataError is a ValueError too (parse_colour's own message)
            raise ParameterError(f"{name}: {exc.message}", where=where) from None
        except (TypeError, ValueError, OverflowError):  # OverflowError: int(inf)
            raise ParameterError(f"{name}={value!r} is not a valid {self.type}", where=where) from None
        if self.type in ("float", "int"):
            if not math.isfinite(value):
                raise ParameterError(f"{name}={value} is not a finite number", where=where)
            if self.min is not None and value < self.min:
                raise ParameterError(f"{name}={value}{unit} is below the minimum {self.min}{unit}", where=where)
            if self.max is not None and value > self.max:
                raise ParameterError(f"{name}={value}{unit} is above the maximum {self.max}{unit}", where=where)
        if self.choices is not None and value not in self.choices:
            close = difflib.get_close_matches(str(value), self.choices, n=1, cutoff=0.6)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise ParameterError(f"{name}={value!r} is not one of {', '.join(self.choices)}{hint}", where=where)
        return value

    def describe(self, name: str) -> dict:
        """The declaration as plain data (``sengine nodes --json``)."""
        return {
            "name": name,
            "type": self.type,
            "default": self.default,
            "min": self.min,
            "max": self.max,
            "choices": list(self.choices) if self.choices else None,
            "unit": self.unit,
            "doc": self.doc,
            **({"count": self.count} if self.count > 1 else {}),
        }


def unknown_name(what: str, name: str, known) -> str:
    """``unknown parameter 'lot-aera'; did you mean 'lot-area'? (parameters: ...)``."""
    close = difflib.get_close_matches(name, list(known), n=1, cutoff=0.6)
    hint = f"; did you mean {close[0]!r}?" if close else ""
    return f"unknown {what} {name!r}{hint} ({what}s: {', '.join(known) or 'none'})"


class Params(Mapping[str, Any]):
    """Checked parameter values; read as ``p["spacing"]`` or ``p.spacing``."""

    def __init__(self, values: Mapping[str, Any]):
        self._values = MappingProxyType(dict(values))

    def __reduce__(self):  # picklable for worker processes
        return (Params, (dict(self._values),))

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):
            raise AttributeError(name)
        try:
            return self._values[name]
        except KeyError:
            raise AttributeError(name) from None

    def __getitem__(self, name: str) -> Any:
        return self._values[name]

    def __iter__(self):
        return iter(self._values)

    def __len__(self) -> int:
        return len(self._values)

    def __repr__(self) -> str:
        return f"Params({dict(self._values)!r})"


@dataclass(frozen=True)
class NodeResult(Mapping):
    """What :meth:`SENode.run` returns: the output layers by port, and the node's report.

    Reads as the dict of layers it holds (``node.run(...)["lots"]``).  ``run`` may also return ``(layers, report)`` or only the ``layers`` dict;
    the executor turns every form into a NodeResult (:meth:`of`).  The
    report is a JSON-able dict of counts that goes into ``stats.json`` under
    the node's id.

    Parameters
    ----------
    layers : dict of str to Layer
        One layer per declared output port.
    report : dict, optional
        Counts and sums of the run (``{"lots": 7471, ...}``).
    """

    layers: Mapping[str, Layer]
    report: Mapping[str, Any] | None = None

    def __getitem__(self, port: str) -> Layer:
        return self.layers[port]

    def __iter__(self):
        return iter(self.layers)

    def __len__(self) -> int:
        return len(self.layers)

    @classmethod
    def of(cls, node: SENode, value: Any) -> NodeResult:
        """Normalise what ``node.run`` returned; raise NodeError for a wrong shape.

        Accepted: a NodeResult, a dict of layers, a ``(dict, report)`` pair, or
        ``None`` for a node without outputs.  The old way of handing a report,
        setting ``self.report`` in ``run``, is still read when the returned
        value carries none.
        """
        report = None
        if isinstance(value, NodeResult):
            layers, report = value.layers, value.report
        elif isinstance(value, tuple) and len(value) == 2 and isinstance(value[0], Mapping | type(None)):
            layers, report = value
        elif value is None and not node.outputs:
            layers = {}
        else:
            layers = value
        if layers is None and not node.outputs:
            layers = {}
        if not isinstance(layers, Mapping):
            raise NodeError(
                f"run() returned {type(value).__name__}, expected a dict of output layers "
                f"({', '.join(node.outputs) or 'none'}), a (dict, report) pair or a NodeResult",
                where=node.where,
            )
        if report is None:
            report = getattr(node, "report", None)
        if report is not None and not isinstance(report, Mapping):
            raise NodeError(
                f"run() returned a report of type {type(report).__name__}, expected a dict", where=node.where
            )
        missing = [p for p in node.outputs if p not in layers]
        extra = [p for p in layers if p not in node.outputs]
        wrong = [p for p, v in layers.items() if p in node.outputs and not isinstance(v, Layer)]
        if missing or extra or wrong:
            why = []
            if missing:
                why.append(f"missing {', '.join(map(repr, missing))}")
            if extra:
                why.append(f"undeclared {', '.join(map(repr, map(str, extra)))}")
            if wrong:
                why.append(", ".join(f"{p!r} is a {type(layers[p]).__name__}, not a Layer" for p in wrong))
            raise NodeError(
                f"run() returned ports {sorted(map(str, layers))}, declared {sorted(node.outputs)} ({'; '.join(why)})",
                where=node.where,
            )
        return cls({p: layers[p] for p in node.outputs}, dict(report) if report else None)


@dataclass
class Context:
    """What a network run shares with its nodes.

    Attributes
    ----------
    seed : int
        The network seed.
    plan : object
        The city plan from the configuration (opaque to the engine).  Only
        the plan's source nodes (:attr:`SENode.source_for`) read it; every
        other node takes the plan's maps and rules on declared input ports.
    base_dir : pathlib.Path or None
        Folder that relative paths in the configuration are relative to.
    out : pathlib.Path or None
        Folder the run writes into (a temporary folder until it completes).
    formats : frozenset of str
        Output formats asked for (``--format``).
    workers : int
        Processes the run may use (``--workers``); exporters write files side by side.
    options : dict
        Output options for exporter nodes (``--crs``, ``--origin``: ``{"crs": "utm", "origin": "local"}``).
    name : str
        The city's name (``<city name="...">``, or the map file's for ``sengine osm``): exporters title
        what they write with it.
    """

    seed: int = 0
    plan: Any = None
    base_dir: Any = None
    out: Any = None
    formats: frozenset = frozenset()
    workers: int = 1
    options: dict = field(default_factory=dict)
    name: str = ""


class SENode:
    """Abstract base of every node.

    Subclasses set the class attributes and implement :meth:`run`.
    ``maps_features`` says that the node maps each input feature on its own
    (lots per block, buildings per lot), so the executor may chunk its input.

    ``source_for`` names a layer kind the node is *the source of* for the
    city plan (``"raster"``: the plan's image maps; ``"rules"``: its
    ``<district>`` / ``<landuse>`` rules).  When a configuration is loaded,
    every unconnected input port of that kind is wired to such a node, made
    by the class's :meth:`plan_source` from the plan, so every input of a
    city is a node on the graph (``sengine graph`` draws it).
    """

    name: ClassVar[str] = ""
    inputs: ClassVar[Mapping[str, Port]] = {}
    outputs: ClassVar[Mapping[str, Port]] = {}
    params: ClassVar[Mapping[str, Param]] = {}
    maps_features: ClassVar[bool] = False
    source_for: ClassVar[str | None] = None
    #: The input port holding the enclosures (areas enclosed by major roads) along which a sharded
    #: run (:mod:`sengine.shard`) splits the city at this node; the node implements :meth:`shard_inputs`.
    shard_port: ClassVar[str | None] = None
    #: The formats a sink writes shard by shard (:meth:`write_shard`), when it can.
    shard_formats: ClassVar[tuple[str, ...]] = ()
    #: Input ports whose features the node hands on or fills (a stream such as ``parks``).  In a
    #: sharded run a layer made for the whole city that reaches such a port is cut: each shard gets
    #: the features whose inner point lies in one of its enclosures, the remainder those outside
    #: every enclosure, so each feature comes out of one shard (:mod:`sengine.shard`).
    shard_streams: ClassVar[tuple[str, ...]] = ()
    #: Input ports :meth:`early` reads: once the layers reaching them are made, a run with workers
    #: starts the node's early job in another process while the nodes in between run here.
    early_inputs: ClassVar[tuple[str, ...]] = ()

    def __init__(
        self,
        node_id: str,
        values: Mapping[str, Any] | None = None,
        context: Context | None = None,
        *,
        where: str | None = None,
    ):
        self.id = node_id
        self.context = context or Context()
        self.where = where or f"node '{node_id}' ({self.name})"
        self.p = self.check_params(values or {}, self.where)

    # -- declaration checks --------------------------------------------------
    @classmethod
    def check_params(cls, values: Mapping[str, Any], where: str) -> Params:
        """Check ``values`` against the declaration; fill in defaults."""
        unknown = sorted(set(values) - set(cls.params))
        if unknown:
            raise ParameterError(unknown_name("parameter", unknown[0], cls.params), where=where)
        out = {}
        for name, decl in cls.params.items():
            if name in values:
                out[name] = decl.coerce(values[name], where, name)
            elif decl.default is None:
                raise ParameterError(f"parameter {name!r} is required", where=where)
            else:
                out[name] = decl.default
        return Params(out)

    @classmethod
    def check_declaration(cls) -> None:
        """Raise TypeError when ``run``'s keywords differ from the input ports."""
        sig = inspect.signature(cls.run)
        names = [n for n, p in sig.parameters.items() if n != "self" and p.kind is p.KEYWORD_ONLY]
        if set(names) != set(cls.inputs):
            raise TypeError(
                f"{cls.__name__}.run keyword-only arguments {sorted(names)} "
                f"differ from its input ports {sorted(cls.inputs)}"
            )
        for name, decl in cls.params.items():
            if decl.default is not None:
                decl.coerce(decl.default, cls.__name__, name)

    # -- randomness ----------------------------------------------------------
    def rng(self, *key: int | str) -> np.random.Generator:
        """A generator seeded from (network seed, node id, *key).

        Called with a feature id it gives the per-feature generator, so a
        feature's draws do not depend on which other features share its batch.
        """
        return generator(self.context.seed, self.id, *key)

    # -- plan sources ----------------------------------------------------------
    @classmethod
    def plan_source(cls, key: str, plan: Any) -> tuple[dict[str, Any], str] | None:
        """Parameters and ``where`` of the source node for the plan's item ``key``.

        ``key`` is a map kind (for an input port named ``<key>_map``) or a
        rule tag (``<key>_rules``).  ``None`` when the plan has nothing for
        it: the port then stays unconnected.  Only classes that set
        :attr:`source_for` implement it.
        """
        return None

    # -- work ----------------------------------------------------------------
    def run(self, **inputs: Layer) -> dict[str, Layer] | NodeResult | tuple:  # pragma: no cover - abstract
        """Compute the output layers from the input layers.

        Returns
        -------
        NodeResult or dict or tuple
            ``NodeResult(layers, report)``, ``(layers, report)`` or ``layers``
            alone: a dict of one Layer per declared output port.
        """
        raise NotImplementedError

    def early(self, **inputs: Layer | None) -> Any:
        """A job (a callable without arguments) to start before the node's other inputs are made, or ``None``.

        ``inputs`` are the layers reaching :attr:`early_inputs` (``None`` for
        an unconnected port).  The job runs in a forked process; :meth:`run`
        gets its result from :meth:`early_result` and must write the same
        output as without it (a run with one worker starts no early job).
        """
        return None

    def early_started(self) -> bool:
        """Whether this run started the node's early job (its result not yet taken)."""
        return "_early_job" in self.__dict__

    def early_result(self) -> Any:
        """The result of this run's early job (:meth:`early`), or ``None`` when none ran: :meth:`run` does the work."""
        job = self.__dict__.pop("_early_job", None)
        return None if job is None else job.result()

    def counted(self, layers: Mapping[str, Layer]) -> int:
        """How many features this node made, for the run's counts line and ``stats.json``.

        Its first output's length; a node whose first output is a stream it
        hands on (parks, roads) counts what it added to it.
        """
        first = next(iter(layers.values()), None)
        return len(first) if first is not None else 0

    def check(self, **inputs: Layer | None) -> None:
        """Checks that need no geometry, run by ``sengine validate`` (optional).

        Called with the layers of the plan's source nodes (image maps,
        rules) on the ports they feed and ``None`` on every other port.
        Raise an :class:`~sengine.errors.SEngineError` for a problem (several
        at once as :class:`~sengine.errors.Problems`).
        """

    # -- sharded runs (sengine.shard) -----------------------------------------
    def shard_inputs(self, inputs: dict[str, Layer | None], rows: np.ndarray) -> dict[str, Layer | None]:
        """The node's inputs for one shard: the enclosures at ``rows`` of its :attr:`shard_port` layer.

        Empty ``rows`` asks for the remainder: what lies outside every
        enclosure.  Only a node that sets :attr:`shard_port` implements it.
        """
        raise NotImplementedError

    def shard_refusal(self, connected: frozenset[str]) -> str | None:
        """Why this node, with its parameters, cannot run one enclosure group at a time (None: it can).

        Asked of every node after the face tracer before a sharded run does
        any work (``connected``: its connected input ports); a reason makes
        the run fail in one line.  A node whose result for a feature depends
        on features of other enclosures (a share of the whole city, a rank
        among all blocks) returns one.
        """
        return None

    def write_shard(self, inputs: dict[str, Layer | None], *, shard: int, city_ports: frozenset) -> Any:
        """A sink (a node without outputs) in a sharded run: write shard ``shard``'s part; return a small summary.

        ``inputs`` on ``city_ports`` are the whole city's layers (made once,
        before the shards: written by :meth:`finish_shards`), the others the
        shard's.  Nodes that cannot write shard by shard leave it raising.
        """
        raise NotImplementedError

    def join_shard(self, part: Any, *, shard: int) -> None:
        """A sink in a sharded run, optionally: take shard ``shard``'s part as soon as it and those before it are done.

        Called in the process that started the run, in shard order, while
        later shards still run (a writer streams the part into its file);
        :meth:`finish_shards` then gets every part again.
        """

    def finish_shards(self, inputs: dict[str, Layer | None], parts: list, *, city_ports: frozenset) -> dict:
        """A sink in a sharded run, once every shard is written: join the parts ``write_shard`` returned.

        ``inputs`` hold the whole city's layers on ``city_ports`` (None on
        the other ports); ``parts`` the summaries in shard order.  Returns
        the node's report.
        """
        raise NotImplementedError

    @classmethod
    def describe(cls) -> dict:
        """The declaration as plain data (``sengine nodes --json``)."""
        return {
            "name": cls.name,
            "doc": (inspect.getdoc(cls) or "").split("\n\n")[0].replace("\n", " "),
            "inputs": [
                {"name": k, "kind": p.kind, "required": p.required, "doc": p.doc} for k, p in cls.inputs.items()
            ],
            "outputs": [{"name": k, "kind": p.kind, "doc": p.doc} for k, p in cls.outputs.items()],
            "params": [p.describe(k) for k, p in cls.params.items()],
            "maps_features": cls.maps_features,
        }
