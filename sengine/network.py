"""Network: build, validate and run a DAG of registered nodes (skylineEngine §5.1).

A :class:`Network` holds node specifications (id, registered type, parameter
values) and connections between their ports.  :meth:`Network.validate`
instantiates every node and checks the whole graph, collecting every problem
before reporting; :meth:`Network.run` runs the nodes in topological order and
keeps per-node counts and seconds.

The standard networks of the paper (stdNetwork, patternNetwork,
stdLoadMapNetwork) are city knowledge: they live in the node library
(:mod:`sengine.nodes.standard`) and are found through the registry.

References
----------
.. [1] R. Ridorsa and G. Patow, "skylineEngine: an urban procedural modelling system",
   technical report, Geometry and Graphics Group, Universitat de Girona, 2011
   (the specification: paper 002 in shared/papers).
"""

from __future__ import annotations

import heapq
import json
import logging
import os
import shutil
import tempfile
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from functools import partial
from graphlib import CycleError, TopologicalSorter
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from . import __version__, registry
from . import progress as _progress
from .errors import NetworkError, NodeError, OutputError, Problems, SEngineError
from .layer import Layer
from .node import Context, NodeResult, SENode
from .parallel import Background, run_jobs
from .plan import CityPlan

if TYPE_CHECKING:
    import networkx as nx

__all__ = ["NodeSpec", "Connection", "Network", "Result"]

log = logging.getLogger(__name__)


@dataclass
class NodeSpec:
    """A node as the configuration names it: id, registered type, parameter values."""

    id: str
    type: str
    params: dict[str, Any] = field(default_factory=dict)
    where: str = ""
    param_where: dict[str, str] = field(default_factory=dict)

    def label(self) -> str:
        """``file:line: node 'id' (type)`` for messages."""
        return f"{self.where}: node '{self.id}' ({self.type})" if self.where else f"node '{self.id}' ({self.type})"


@dataclass(frozen=True)
class Connection:
    """An edge from ``src`` (optionally ``.src_port``) to ``dst`` (``.dst_port``)."""

    src: str
    src_port: str | None
    dst: str
    dst_port: str | None
    where: str = ""

    @classmethod
    def parse(cls, src: str, dst: str, where: str = "") -> Connection:
        """A connection from ``"node"`` or ``"node.port"`` to ``"node"`` or ``"node.port"``."""
        s, _, sp = src.partition(".")
        d, _, dp = dst.partition(".")
        return cls(s, sp or None, d, dp or None, where)


@dataclass
class Result:
    """What a run returns: the output layers of every node, and the stats.

    Unpacks as ``layers, stats = network.run(...)``; ``result["blocks"]`` is
    the first output layer of node ``blocks``.
    """

    layers: dict[str, dict[str, Layer]]
    stats: dict[str, Any]

    def __iter__(self) -> Iterator[Any]:
        return iter((self.layers, self.stats))

    def __getitem__(self, node_id: str) -> Layer:
        outs = self.layers[node_id]
        return next(iter(outs.values()))


@dataclass
class _Bound:
    """A validated network: node instances, resolved edges, run order."""

    nodes: dict[str, SENode]
    edges: list[tuple[str, str, str, str]]  # src, src_port, dst, dst_port
    order: list[str]


ProgressFn = Callable[[int, int, str, str, int, float], None]  # or a sengine.progress.Progress


def layer_area(outputs: Mapping[str, Layer], count: int) -> float:
    """The area ``stats.json`` gives a node: its first output layer's (m2), 0 when it made nothing."""
    first = next(iter(outputs.values()), None)
    return first.area() if first is not None and count else 0.0


class Network:
    """A DAG of registered nodes.

    Parameters
    ----------
    plan : CityPlan, optional
        The city plan the nodes read.
    seed : int
        Default seed for :meth:`run`.
    base_dir : path-like, optional
        Folder that relative paths are resolved against.
    source : str
        What the network was loaded from (for stats and messages).
    """

    def __init__(self, *, plan: CityPlan | None = None, seed: int = 0, base_dir: Any = None, source: str = ""):
        self.specs: dict[str, NodeSpec] = {}
        self.connections: list[Connection] = []
        self.plan = plan if plan is not None else CityPlan()
        self.seed = int(seed)
        self.base_dir = Path(base_dir) if base_dir is not None else None
        self.source = source

    # -- building -------------------------------------------------------------
    def add(self, node_id: str, type: str, params: Mapping[str, Any] | None = None, *, where: str = "") -> NodeSpec:
        """Add a node; a duplicate id is an error."""
        if node_id in self.specs:
            old = self.specs[node_id]
            raise NetworkError(
                f"node id {node_id!r} is defined twice (first at {old.where or 'an earlier line'})", where=where or None
            )
        spec = NodeSpec(node_id, type, dict(params or {}), where, {k: where for k in (params or {})})
        self.specs[node_id] = spec
        return spec

    def replace(self, node_id: str, type: str, *, where: str = "") -> None:
        """Put a node of another type behind an existing id (an association)."""
        spec = self._spec(node_id, where)
        spec.type = type
        spec.where = where or spec.where

    def set_param(self, node_id: str, name: str, value: Any, *, where: str = "") -> None:
        """Set one parameter of one node (checked at validation)."""
        spec = self._spec(node_id, where)
        spec.params[name] = value
        spec.param_where[name] = where

    def connect(self, src: str, dst: str, *, where: str = "") -> None:
        """Connect ``"node"`` or ``"node.port"`` to ``"node"`` or ``"node.port"``."""
        self.connections.append(Connection.parse(src, dst, where))

    def disconnect(self, src: str, dst: str, *, where: str = "") -> None:
        """Remove the connections from ``src`` to ``dst`` (a port left out matches any)."""
        want = Connection.parse(src, dst)
        keep = [
            c
            for c in self.connections
            if not (
                c.src == want.src
                and c.dst == want.dst
                and want.src_port in (None, c.src_port)
                and want.dst_port in (None, c.dst_port)
            )
        ]
        if len(keep) == len(self.connections):
            raise NetworkError(f"there is no connection from {src!r} to {dst!r} to remove", where=where or None)
        self.connections = keep

    def _spec(self, node_id: str, where: str = "") -> NodeSpec:
        try:
            return self.specs[node_id]
        except KeyError:
            known = ", ".join(self.specs) or "none"
            raise NetworkError(
                f"no node with id {node_id!r} in the network (nodes: {known})", where=where or None
            ) from None

    def merge(self, other: Network) -> None:
        """Add every node and connection of ``other`` (ids must not clash)."""
        for spec in other.specs.values():
            self.add(spec.id, spec.type, spec.params, where=spec.where)
            self.specs[spec.id].param_where.update(spec.param_where)
        self.connections.extend(other.connections)

    # -- validation -------------------------------------------------------------
    def validate(self, context: Context | None = None) -> _Bound:
        """Check the whole network; raise every problem at once (:class:`~sengine.errors.Problems`).

        Checks: unknown node type, unknown or missing port, port kind
        mismatch, missing required input, input connected twice, unknown
        parameter, value out of bounds, and cycles (naming their node ids).
        """
        context = context or self._context(self.seed)
        problems: list[SEngineError] = []
        nodes: dict[str, SENode] = {}
        for spec in self.specs.values():
            try:
                cls = registry.get(spec.type, where=spec.label())
                values = dict(spec.params)
                nodes[spec.id] = cls(spec.id, values, context, where=spec.label())
            except SEngineError as err:
                where = self._param_where(spec, err)
                problems.append(type(err)(err.message, where=where or err.where))
        edges: list[tuple[str, str, str, str]] = []
        taken: dict[tuple[str, str], Connection] = {}
        tainted: set[str] = set()  # nodes with a connection that failed: a missing input would only echo it
        for conn in self.connections:
            try:
                edge = self._resolve(conn, nodes, taken)
            except SEngineError as err:
                problems.append(err)
                tainted.add(conn.dst)
                continue
            if edge is not None:
                taken[(edge[2], edge[3])] = conn
                edges.append(edge)
            else:
                tainted.add(conn.dst)
        for node_id, node in nodes.items():
            if node_id in tainted:
                continue
            for port_name, port in node.inputs.items():
                if port.required and (node_id, port_name) not in taken:
                    problems.append(
                        NetworkError(
                            f"required input {port_name!r} (kind {port.kind!r}) is not connected",
                            where=self.specs[node_id].label(),
                        )
                    )
        order: list[str] = []
        try:
            order = _run_order(list(self.specs), [(e[0], e[2]) for e in edges])
        except CycleError as cycle:
            problems.append(
                NetworkError(f"the network has a cycle: {' -> '.join(cycle.args[1])}", where=self.source or None)
            )
        Problems.raise_if(problems, where=self.source or None)
        # the plan's inputs first: a missing or broken map fails before any work is done
        order = [k for k in order if nodes[k].source_for] + [k for k in order if not nodes[k].source_for]
        return _Bound(nodes, edges, order)

    @staticmethod
    def _param_where(spec: NodeSpec, err: SEngineError) -> str | None:
        for name, where in spec.param_where.items():
            if where and (f"{name}=" in err.message or f"{name!r}" in err.message):
                return f"{where}: node '{spec.id}' ({spec.type})"
        return None

    def _resolve(
        self, conn: Connection, nodes: Mapping[str, SENode], taken: Mapping[tuple[str, str], Connection]
    ) -> tuple[str, str, str, str] | None:
        where = conn.where or None
        for end in (conn.src, conn.dst):
            if end not in self.specs:
                known = ", ".join(self.specs) or "none"
                raise NetworkError(f"connection names unknown node {end!r} (nodes: {known})", where=where)
        src, dst = nodes.get(conn.src), nodes.get(conn.dst)
        if src is None or dst is None:
            return None  # the node itself is already reported
        if conn.src_port is not None and conn.src_port not in src.outputs:
            raise NetworkError(
                f"node '{conn.src}' ({src.name}) has no output {conn.src_port!r}"
                f" (outputs: {', '.join(src.outputs) or 'none'})",
                where=where,
            )
        if conn.dst_port is not None and conn.dst_port not in dst.inputs:
            raise NetworkError(
                f"node '{conn.dst}' ({dst.name}) has no input {conn.dst_port!r}"
                f" (inputs: {', '.join(dst.inputs) or 'none'})",
                where=where,
            )
        if not src.outputs:
            raise NetworkError(f"node '{conn.src}' ({src.name}) has no outputs to connect", where=where)
        if not dst.inputs:
            raise NetworkError(f"node '{conn.dst}' ({dst.name}) has no inputs to connect", where=where)
        src_ports = [conn.src_port] if conn.src_port else list(src.outputs)
        dst_ports = [conn.dst_port] if conn.dst_port else [p for p in dst.inputs if (conn.dst, p) not in taken]
        for sp in src_ports:
            for dp in dst_ports:
                if dst.inputs[dp].accepts(src.outputs[sp].kind):
                    if (conn.dst, dp) in taken:
                        first = taken[(conn.dst, dp)]
                        raise NetworkError(
                            f"input '{conn.dst}.{dp}' is connected twice "
                            f"(also from '{first.src}' at {first.where or 'another line'})",
                            where=where,
                        )
                    return (conn.src, sp, conn.dst, dp)
                if not conn.src_port:
                    continue
        out_kinds = ", ".join(f"{p}:{src.outputs[p].kind}" for p in src_ports)
        in_kinds = ", ".join(f"{p}:{dst.inputs[p].kind}" for p in dst_ports) or "none free"
        raise NetworkError(
            f"port kind mismatch: '{conn.src}' gives {out_kinds} but '{conn.dst}' takes {in_kinds}", where=where
        )

    # -- the plan's inputs -------------------------------------------------------
    def wire_plan(self) -> list[str]:
        """Give the plan's inputs source nodes on the graph; return the ids of the nodes added.

        One node per map of the plan, ``<kind>Map``, of the type that is the
        source of the map kind's port kind (:func:`~sengine.registry.declare_map_kind`,
        :attr:`SENode.source_for`), even when nothing takes it yet (so
        ``validate`` reads it).  Then every unconnected input port named
        ``<key>_<suffix>`` whose kind some class is the source of is
        connected to node ``<key><Suffix>`` (``height_map`` <- ``heightMap``,
        ``district_rules`` <- ``districtRules``), made by that class's
        :meth:`~sengine.node.SENode.plan_source` when missing.  Ports the
        plan has nothing for stay unconnected.  Idempotent; unknown node
        types are left for :meth:`validate`.
        """
        sources = registry.source_classes()
        added: list[str] = []

        def ensure(node_id: str, cls: type[SENode], key: str) -> bool:
            if node_id in self.specs:
                return True
            made = cls.plan_source(key, self.plan)
            if made is None:
                return False
            params, where = made
            self.add(node_id, cls.name, params, where=where)
            added.append(node_id)
            return True

        for kind in self.plan.maps:
            port_kind = registry.map_kinds().get(kind, (None, ""))[0]
            if port_kind in sources:
                ensure(f"{kind}Map", sources[port_kind], kind)
        named = {(c.dst, c.dst_port) for c in self.connections if c.dst_port}
        for spec in list(self.specs.values()):
            cls = registry.find(spec.type)
            if cls is None or cls.source_for:
                continue
            for port_name, port in cls.inputs.items():
                src_cls = sources.get(port.kind)
                key, _, suffix = port_name.rpartition("_")
                if src_cls is None or not key or (spec.id, port_name) in named:
                    continue
                node_id = f"{key}{suffix.capitalize()}"
                if ensure(node_id, src_cls, key):
                    self.connect(f"{node_id}", f"{spec.id}.{port_name}", where=self.specs[node_id].where)
        return added

    def check(self) -> Result:
        """Every check that needs no geometry, as ``sengine validate`` runs it.

        Validates the network, runs the plan's source nodes (they read the
        image maps and rules: missing, unreadable or misshapen files fail
        here) and then each node's :meth:`~sengine.node.SENode.check` with
        the source layers it takes (known map colours ...).  Every problem is
        collected and raised at once.  Returns the source layers.
        """
        bound = self.validate()
        problems: list[SEngineError] = []
        layers: dict[str, dict[str, Layer]] = {}
        for node_id in bound.order:
            node = bound.nodes[node_id]
            if node.source_for is None or node.inputs:
                continue
            try:
                layers[node_id] = dict(_call_run(node, {}).layers)
            except SEngineError as err:
                problems.append(err)
        feeds: dict[str, dict[str, Layer | None]] = {}
        for s, sp, d, dp in bound.edges:
            if s in layers:
                feeds.setdefault(d, {})[dp] = layers[s][sp]
        for node_id in bound.order:
            node = bound.nodes[node_id]
            if node_id in layers or type(node).check is SENode.check:
                continue
            kwargs = {p: feeds.get(node_id, {}).get(p) for p in node.inputs}
            try:
                node.check(**kwargs)
            except SEngineError as err:
                problems.append(err)
        Problems.raise_if(problems, where=self.source or None)
        return Result(layers, {})

    # -- running --------------------------------------------------------------
    def _context(
        self,
        seed: int,
        out: Path | None = None,
        formats: Iterable[str] = (),
        workers: int = 1,
        options: Mapping[str, Any] | None = None,
    ) -> Context:
        return Context(
            seed=int(seed),
            plan=self.plan,
            base_dir=self.base_dir,
            out=out,
            formats=frozenset(formats),
            workers=workers,
            options=dict(options or {}),
            name=str(getattr(self.plan, "name", "") or ""),
        )

    def run(
        self,
        seed: int | None = None,
        out: Any = None,
        *,
        formats: Iterable[str] = (),
        progress: ProgressFn | _progress.Progress | None = None,
        workers: int = 1,
        options: Mapping[str, Any] | None = None,
        check_kinds: bool = False,
    ) -> Result:
        """Validate, then run every node in topological order.

        Parameters
        ----------
        seed : int, optional
            Network seed; defaults to the configuration's.
        out : path-like, optional
            Output folder.  Files are written into a temporary folder beside
            it and moved in only when the whole run succeeded, with
            ``stats.json`` last.
        formats : iterable of str
            Output formats for exporter nodes (empty: their defaults).
        progress : callable or sengine.progress.Progress, optional
            A callable is called after each node as ``progress(i, n, node_id,
            type, count, seconds)``; an object with ``start``, ``advance``,
            ``finish`` and ``close`` methods hears when each node starts, how
            far a node that counts its work (chunks of features, exporters'
            writers) has got, and when it finishes (:mod:`sengine.progress`;
            :class:`~sengine.progress.TerminalProgress` draws bars).
        workers : int
            Worker processes: nodes that map features one by one get their
            first input cut into chunks, exporters write their files side by
            side, and a node's early job (:meth:`SENode.early`: the
            exporter's roofs) starts in another process as soon as the
            layers it needs are made.  The result is the same for any
            number of workers.
        options : mapping, optional
            Output options for exporter nodes (``crs``, ``origin``).

        Raises
        ------
        ParameterError
            A format no registered node writes (with a suggestion).
        check_kinds : bool
            Check every output layer against its port kind's declared
            columns and dtypes (``--debug``; see :func:`sengine.registry.declare_kind`).
        """
        seed = self.seed if seed is None else int(seed)
        formats = registry.check_formats(formats)
        out_dir = Path(out) if out is not None else None
        events = _progress.as_progress(progress)
        tmp = _output_folder(out_dir) if out_dir is not None else None
        try:
            result = self._run(seed, tmp, formats, events, max(1, int(workers)), options, check_kinds)
            if tmp is not None:
                _write_json(tmp / "stats.json", result.stats)
                _move_into(tmp, out_dir)
            return result
        finally:
            if events is not None:
                events.close()
            if tmp is not None and tmp.exists():
                shutil.rmtree(tmp, ignore_errors=True)

    def _run(
        self,
        seed: int,
        tmp: Path | None,
        formats: Iterable[str],
        events: _progress.Progress | None,
        workers: int,
        options: Mapping[str, Any] | None = None,
        check_kinds: bool = False,
    ) -> Result:
        t_start = time.perf_counter()
        context = self._context(seed, tmp, formats, workers, options)
        bound = self.validate(context)
        incoming: dict[str, list[tuple[str, str, str]]] = {k: [] for k in bound.nodes}
        for s, sp, d, dp in bound.edges:
            incoming[d].append((s, sp, dp))
        layers: dict[str, dict[str, Layer]] = {}
        counts: dict[str, int] = {}
        seconds: dict[str, float] = {}
        areas: dict[str, float] = {}
        report: dict[str, Any] = {}
        n = len(bound.order)
        early = _EarlyJobs(bound, incoming, workers)  # nodes' work started ahead in other processes
        try:
            for i, node_id in enumerate(bound.order, 1):
                node = bound.nodes[node_id]
                kwargs = {p: None for p in node.inputs}
                for s, sp, dp in incoming[node_id]:
                    kwargs[dp] = layers[s][sp]
                t0 = time.perf_counter()
                with _progress.step(events, i, n, node_id, node.name):
                    result = _run_node(node, kwargs, workers)
                dt = time.perf_counter() - t0
                if check_kinds:
                    for port_name, lay in result.layers.items():
                        registry.check_kind(
                            lay, node.outputs[port_name].kind, where=f"{node.where} output {port_name!r}"
                        )
                layers[node_id] = dict(result.layers)
                count = node.counted(layers[node_id])
                if node.outputs and not node.source_for:  # sinks (exporters) and the plan's inputs count no features
                    counts[node_id] = count
                seconds[node_id] = round(dt, 4)
                area = layer_area(layers[node_id], count)
                if area > 0:
                    areas[node_id] = round(area, 1)
                if result.report:
                    report[node_id] = result.report
                log.info("%s (%s): %d features in %.3f s", node_id, node.name, count, dt)
                if events is not None:
                    events.finish(i, n, node_id, node.name, count, dt)
                early.start(layers)
        finally:
            early.close()
        seconds["total"] = round(time.perf_counter() - t_start, 4)
        stats = {
            "sengine": __version__,
            "config": self.source,
            "seed": seed,
            "counts": counts,
            "areas": areas,
            "seconds": seconds,
            "report": report,
        }
        return Result(layers, stats)

    # -- inspection -------------------------------------------------------------
    def graph(self) -> nx.MultiDiGraph:
        """The network as a networkx graph (nodes carry ``type``; edges carry ports)."""
        import networkx as nx

        g = nx.MultiDiGraph()
        for spec in self.specs.values():
            g.add_node(spec.id, type=spec.type)
        try:
            bound = self.validate()
            for s, sp, d, dp in bound.edges:
                g.add_edge(s, d, src_port=sp, dst_port=dp)
        except SEngineError:
            for c in self.connections:
                g.add_edge(c.src, c.dst, src_port=c.src_port or "", dst_port=c.dst_port or "")
        return g


def _run_order(nodes: list[str], edges: list[tuple[str, str]]) -> list[str]:
    """A topological order of ``nodes`` that, among the nodes ready to run, always takes the first in file order.

    The standard library's :class:`graphlib.TopologicalSorter`: importing
    networkx (about 0.1 s here) to order a handful of nodes slowed every
    run's start.  Raises its ``CycleError``, whose ``args[1]`` is the cycle
    ``[a, b, ..., a]``.
    """
    index = {k: i for i, k in enumerate(nodes)}
    sorter = TopologicalSorter({k: () for k in nodes})
    for src, dst in edges:
        sorter.add(dst, src)
    sorter.prepare()
    ready: list[tuple[int, str]] = []
    order = []
    while sorter.is_active():
        for k in sorter.get_ready():
            heapq.heappush(ready, (index[k], k))
        _, k = heapq.heappop(ready)
        order.append(k)
        sorter.done(k)
    return order


MIN_CHUNK = 256  # features; the executor times a first chunk of this size before it forks
FORK_AFTER = 0.25  # s; the rest of a node's work must take about this long for workers to pay off


def _run_node(node: SENode, kwargs: dict[str, Layer | None], workers: int) -> NodeResult:
    """Run one node, in chunks over worker processes when it maps features and that pays off.

    The first input is cut into contiguous chunks; other inputs go whole to
    every chunk.  A first chunk runs here and is timed: only when the rest
    would take more than ``FORK_AFTER`` seconds does it go to the workers
    (starting them and sending the results back costs some 0.1 s).  Outputs
    are concatenated in chunk order (renumbered when the node numbers its
    features per call), and the chunks' reports summed, which gives the
    single-process result because a mapping node draws its random numbers
    per feature (``self.rng(feature_id)``) and writes no files.
    """
    first = next(iter(node.inputs), None)
    layer = kwargs.get(first) if first else None
    if workers <= 1 or not node.maps_features or layer is None or len(layer) < 2 * MIN_CHUNK:
        return _call_run(node, kwargs)
    t = time.perf_counter()
    _progress.expect(len(layer), first)  # counted in the input's features: "blocks", "lots" ...
    parts = [_call_run(node, {**kwargs, first: layer.take(np.arange(MIN_CHUNK))}, MIN_CHUNK)]
    rest = len(layer) - MIN_CHUNK
    if (time.perf_counter() - t) * rest / MIN_CHUNK < FORK_AFTER:
        parts.append(_call_run(node, {**kwargs, first: layer.take(np.arange(MIN_CHUNK, len(layer)))}, rest))
    else:
        n_chunks = max(1, min(workers * 4, rest // MIN_CHUNK))
        bounds = np.linspace(MIN_CHUNK, len(layer), n_chunks + 1).astype(int)
        jobs = [
            partial(_call_run, node, {**kwargs, first: layer.take(np.arange(a, b))}, b - a)
            for a, b in zip(bounds[:-1], bounds[1:])
        ]
        parts += run_jobs(jobs, workers)  # forked workers inherit the registry and plugins
    reports = [dict(r.report) for r in parts if r.report]
    merged = {}
    for port in node.outputs:
        layers = [r.layers[port] for r in parts]
        ids = np.concatenate([lay.ids for lay in layers])
        merged[port] = Layer.concat(layers, renumber=len(np.unique(ids)) != len(ids))
    return NodeResult(merged, _sum_reports(reports) if reports else None)


def _call_run(node: SENode, kwargs: dict[str, Layer | None], count: int = 0) -> NodeResult:
    """``node.run(**kwargs)`` as a NodeResult, then ``count`` features counted as done.

    ``count`` is the chunk's features (:func:`sengine.progress.advance`).

    A plugin's node (a class from outside the ``sengine`` package) that
    raises anything but an :class:`~sengine.errors.SEngineError` fails with
    a one-line :class:`~sengine.errors.NodeError` naming the node; the
    built-in nodes' exceptions are bugs and keep their traceback.  Running
    out of memory is one line for every node.
    """
    if "report" in vars(node):  # the old form: a report left by a previous call must not leak into this one
        node.report = None
    try:
        value = node.run(**kwargs)
    except SEngineError:
        raise
    except MemoryError:
        raise NodeError("ran out of memory (try smaller inputs or fewer --workers)", where=node.where) from None
    except Exception as exc:
        if type(node).__module__.split(".")[0] == "sengine":
            raise
        raise NodeError(
            f"failed: {type(exc).__name__}: {exc} (a bug in the plugin; --debug shows the traceback)",
            where=node.where,
        ) from exc
    _progress.advance(count)
    return NodeResult.of(node, value)


def _sum_reports(reports: list[dict]) -> dict:
    """Merge the reports of a node's chunks.

    Numbers add up (``max_*`` ones take the largest); the rest is taken from the first.
    """
    total: dict = {}
    for rep in reports:
        for key, value in rep.items():
            if isinstance(value, dict):
                total[key] = _sum_reports([total.get(key, {}), value])
            elif isinstance(value, (int, float)) and not isinstance(value, bool) and key in total:
                total[key] = max(total[key], value) if key.startswith("max_") else total[key] + value
            else:
                total.setdefault(key, value)
    return total


def check_output_folder(out_dir: Path) -> None:
    """Raise OutputError (one line) unless ``out_dir`` can be made and written (see :func:`_output_folder`)."""
    shutil.rmtree(_output_folder(Path(out_dir)), ignore_errors=True)


def _output_folder(out_dir: Path) -> Path:
    """Check that ``out_dir`` can be written and make the temporary folder beside it, before any work.

    Raises OutputError (one line) when the folder is an existing file, lies
    under a file, cannot be made or written, or has too long a name.
    """
    try:
        if out_dir.exists() and not out_dir.is_dir():
            raise OutputError(f"output folder {str(out_dir)!r} is an existing file")
        out_dir.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.", suffix=".tmp", dir=out_dir.parent))
    except OutputError:
        raise
    except OSError as exc:
        why = exc.strerror or type(exc).__name__
        raise OutputError(f"cannot write the output folder {str(out_dir)!r}: {why}") from None
    if out_dir.exists() and not os.access(out_dir, os.W_OK | os.X_OK):
        shutil.rmtree(tmp, ignore_errors=True)
        raise OutputError(f"cannot write the output folder {str(out_dir)!r}: Permission denied")
    return tmp


def _write_json(path: Path, data: Any) -> None:
    path.write_text(json.dumps(data, indent=2, sort_keys=False) + "\n")


def _move_into(tmp: Path, out_dir: Path) -> None:
    """Move every file of ``tmp`` into ``out_dir``, ``stats.json`` last."""
    out_dir.mkdir(parents=True, exist_ok=True)
    names = sorted(p.name for p in tmp.iterdir())
    names.sort(key=lambda n: n == "stats.json")
    for name in names:
        target = out_dir / name
        if target.is_dir() and not target.is_symlink():
            shutil.rmtree(target)
        os.replace(tmp / name, target)


class _EarlyJobs:
    """The nodes' early jobs (:meth:`SENode.early`) of a run with workers, each started once its inputs are made."""

    def __init__(self, bound, incoming: dict, workers: int):
        self.bound, self.incoming = bound, incoming
        self.waiting: dict[str, set[str]] = {}  # node id -> the nodes whose layers its early inputs wait for
        self.started: list[SENode] = []
        if not Background.startable(workers):
            return
        for node_id, node in bound.nodes.items():
            ports = type(node).early_inputs
            sources = {s for s, _, dp in incoming[node_id] if dp in ports}
            if ports and sources:
                self.waiting[node_id] = sources

    def start(self, layers: dict) -> None:
        """Start the early job of every node whose early inputs are now made and that has not run yet."""
        for node_id in [k for k, w in self.waiting.items() if w <= layers.keys()]:
            del self.waiting[node_id]
            if node_id in layers:
                continue
            node = self.bound.nodes[node_id]
            inputs = dict.fromkeys(type(node).early_inputs)
            for s, sp, dp in self.incoming[node_id]:
                if dp in inputs:
                    inputs[dp] = layers[s][sp]
            job = node.early(**inputs)
            if job is not None:
                node._early_job = Background(job)
                self.started.append(node)

    def close(self) -> None:
        """Stop the early jobs no node asked for (the run failed, or a node did the work itself)."""
        for node in self.started:
            job = node.__dict__.pop("_early_job", None)
            if job is not None:
                job.close()
