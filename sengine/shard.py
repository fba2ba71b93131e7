"""One very large city in shards along its major-road enclosures (issue 13, part 4).

A city whose layers do not fit in memory at once is cut where its street
network cuts it: along the areas enclosed by major roads.  The run goes:

1. **the whole city once**: every node that the face tracer does not feed
   (the maps, the major and minor roads: the street graph is noded once,
   for the whole city) runs as usual;
2. **the shards**: the enclosures are grouped into about ``--shards``
   contiguous groups of balanced area, and one more shard is the
   *remainder*, the land outside every enclosure.  For each, the face
   tracer (the node that declares :attr:`~sengine.node.SENode.shard_port`,
   ``blocks.circuits``) traces the faces of the lines inside and on the
   boundary of the shard's enclosures (:meth:`~sengine.node.SENode.shard_inputs`),
   which are exactly the whole graph's faces there, and every node after
   it (lots, buildings, planning ...) runs on the shard alone.  The sinks
   (``export.city``) write the shard's part
   (:meth:`~sengine.node.SENode.write_shard`).  Shards run on the
   scheduler (:mod:`sengine.scheduler`: local processes, a Dask
   LocalCluster or a Dask cluster elsewhere, whose workers get the whole
   city's layers once each), each in one process, so peak memory is the whole-city street graph plus one
   shard per worker;
3. **the files**: the sinks join the parts in shard order
   (:meth:`~sengine.node.SENode.finish_shards`), streaming them into
   ``<layer>.parquet`` and ``city.gpkg`` a chunk at a time.

The tracer orders its faces by enclosure and derives every id from the
face (enclosure id x 10,000 + rank; a lot's from its block), not from the
run's order, so the shards concatenated in order are the unsharded city:
the same GeoParquet and GeoPackage bytes (tests/test_shard.py).  An earlier
experiment lost faces with tiles and halos, and with re-noding per shard;
tracing per enclosure on the graph noded once loses none.

Nodes after the tracer must be local to an enclosure (a lot is made from
its block alone); one that is not, with its parameters, says why
(:meth:`~sengine.node.SENode.shard_refusal`) and the run stops in one line
before any work.  A layer made for the whole city that reaches a node's
stream port (:attr:`~sengine.node.SENode.shard_streams`: the district
parks handed down the parks stream) is cut by enclosure: each feature goes
to the shard whose enclosure holds its inner point (the remainder: outside
every enclosure), so it comes out of one shard and is filled (trees) once;
its other whole-city inputs (water, rules) every shard gets whole, as
context.  The open-space nodes keep their layers in id order, with ids
derived from the enclosure (:mod:`sengine.nodes.parks.ids`), so the
shards' parts in shard order are again the whole city's layers.  ``stats.json`` holds the shards' counts summed, their
reports merged (sums added; the FAR and coverage of the sums) and the
seconds of every node summed over the shards.
"""

from __future__ import annotations

import logging
import shutil
import time
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from . import __version__, registry
from .errors import ParameterError, SEngineError
from .geom.polygons import containing
from .layer import Layer
from .node import SENode

__all__ = ["group_enclosures", "merge_reports", "run_sharded"]

log = logging.getLogger(__name__)


def group_enclosures(weights, shards: int) -> list[np.ndarray]:
    """Contiguous groups of enclosure rows, about ``shards`` of them, of balanced total ``weights``.

    Returns the rows of each group (in row order); empty groups are left out.
    """
    w = np.asarray(weights, np.float64)
    n = len(w)
    if n == 0:
        return []
    shards = max(1, min(int(shards), n))
    cum = np.cumsum(np.maximum(w, 0.0))
    total = cum[-1] if cum[-1] > 0 else float(n)
    if cum[-1] <= 0:
        cum = np.arange(1, n + 1, dtype=np.float64)
    cuts = np.searchsorted(cum, total * np.arange(1, shards) / shards, side="left") + 1
    bounds = [0]
    for i, c in enumerate(cuts.tolist(), 1):  # at least one enclosure each, room left for the rest
        bounds.append(min(max(int(c), bounds[-1] + 1), n - (shards - i)))
    bounds.append(n)
    return [np.arange(a, b) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]


def merge_reports(reports: list[dict]) -> dict:
    """Merge node reports of shards: numbers add (``max_*`` take the largest), the rest is the first's.

    Where a dict holds ``site_area_m2``, ``footprint_m2`` and
    ``floor_area_m2`` (a planning summary), its ``far`` and ``coverage``
    are those of the sums.
    """
    total: dict = {}
    for rep in reports:
        for key, value in rep.items():
            if isinstance(value, dict):
                total[key] = merge_reports([total.get(key, {}), value])
            elif isinstance(value, (int, float)) and not isinstance(value, bool) and key in total:
                total[key] = max(total[key], value) if key.startswith("max_") else total[key] + value
            else:
                total.setdefault(key, value)
    if {"site_area_m2", "footprint_m2", "floor_area_m2"} <= set(total):
        a = total["site_area_m2"]
        total["far"] = round(total["floor_area_m2"] / a, 4) if a > 0 else 0.0
        total["coverage"] = round(total["footprint_m2"] / a, 4) if a > 0 else 0.0
    for key, value in total.items():
        if isinstance(value, float):
            total[key] = round(value, 4)
    return total


@dataclass
class _City:
    """What every shard task needs: the bound network, the whole city's layers and the shards."""

    bound: Any
    incoming: dict
    city_layers: dict
    shard_nodes: list
    sinks: list
    tracer: str
    shards: list
    city_ports: dict
    streams: dict  # (node id, port) -> enclosure row of each feature of the city layer on that stream port


_CITY: _City | None = None  # set before the scheduler starts: forked workers inherit it


def _inputs(city: _City, node_id: str, layers: Mapping[str, Mapping[str, Layer]]) -> dict:
    node = city.bound.nodes[node_id]
    kwargs: dict = {p: None for p in node.inputs}
    for s, sp, dp in city.incoming[node_id]:
        kwargs[dp] = layers[s][sp]
    return kwargs


def _run_shard(k: int, city: _City | None = None) -> dict:
    """Shard ``k``: the tracer and every node after it on the shard's enclosures, the sinks' parts written.

    ``city`` comes with the task where the worker did not inherit
    :data:`_CITY` (a Dask cluster elsewhere, spawned processes).
    """
    from .network import _run_node, layer_area

    city = city if city is not None else _CITY
    if city is None:
        raise SEngineError("a shard task ran where the city was not made and none was sent")
    t0 = time.perf_counter()
    layers: dict[str, dict[str, Layer]] = dict(city.city_layers)
    counts: dict[str, int] = {}
    seconds: dict[str, float] = {}
    areas: dict[str, float] = {}
    reports: dict[str, dict] = {}
    for node_id in city.shard_nodes:
        node = city.bound.nodes[node_id]
        kwargs = _inputs(city, node_id, layers)
        for (nid, port), host in city.streams.items():
            if nid == node_id:  # the whole city's stream features this shard owns
                rows = city.shards[k]
                mine = np.isin(host, rows) if len(rows) else host < 0
                kwargs[port] = kwargs[port].take(np.flatnonzero(mine))
        if node_id == city.tracer:
            kwargs = node.shard_inputs(kwargs, city.shards[k])
        t = time.perf_counter()
        result = _run_node(node, kwargs, 1)
        seconds[node_id] = time.perf_counter() - t
        layers[node_id] = dict(result.layers)
        counts[node_id] = node.counted(result.layers)
        areas[node_id] = layer_area(result.layers, counts[node_id])
        if result.report:
            reports[node_id] = dict(result.report)
    parts = {}
    for node_id in city.sinks:
        node = city.bound.nodes[node_id]
        t = time.perf_counter()
        parts[node_id] = node.write_shard(_inputs(city, node_id, layers), shard=k, city_ports=city.city_ports[node_id])
        seconds[node_id] = time.perf_counter() - t
    return {
        "shard": k,
        "counts": counts,
        "areas": areas,
        "seconds": seconds,
        "reports": reports,
        "parts": parts,
        "total": time.perf_counter() - t0,
    }


def run_sharded(
    net,
    *,
    out,
    shards: int,
    seed: int | None = None,
    formats: Iterable[str] = (),
    progress=None,
    workers: int = 1,
    options: Mapping[str, Any] | None = None,
    scheduler: str = "local",
):
    """Run ``net`` in shards along its major-road enclosures into folder ``out`` (see the module notes).

    Parameters
    ----------
    net : sengine.network.Network
        A network with a face tracer that declares a ``shard_port`` fed by
        the enclosures (the pattern network's ``blocks``).
    out : path-like
        Output folder (written into a temporary folder beside it and moved
        in when complete, ``stats.json`` last).
    shards : int
        About how many shards (plus the remainder).
    seed, formats, progress, workers, options
        As :meth:`sengine.network.Network.run`; ``workers`` processes run
        the shards side by side.
    scheduler : str
        ``local``, ``dask`` or a Dask cluster's address ``tcp://HOST:PORT``
        (:func:`sengine.scheduler.make_scheduler`); checked before any work.

    Returns
    -------
    sengine.network.Result
        The whole city's layers (not the shards') and the stats.
    """
    global _CITY
    from .network import Result, _move_into, _output_folder, _run_node, _write_json, layer_area
    from .scheduler import check_scheduler, make_scheduler

    t_start = time.perf_counter()
    seed = net.seed if seed is None else int(seed)
    formats = registry.check_formats(formats)
    scheduler = check_scheduler(scheduler)
    out_dir = Path(out)
    tmp = _output_folder(out_dir)
    try:
        context = net._context(seed, tmp, formats, 1, options)
        bound = net.validate(context)
        incoming: dict[str, list] = {k: [] for k in bound.nodes}
        for s, sp, d, dp in bound.edges:
            incoming[d].append((s, sp, dp))
        tracers = [
            k
            for k in bound.order
            if bound.nodes[k].shard_port and any(dp == bound.nodes[k].shard_port for _, _, dp in incoming[k])
        ]
        if not tracers:
            raise SEngineError(
                "--shards needs a network whose blocks are traced within areas enclosed by major roads "
                "(a node with a shard port, fed: the pattern network's blocks.circuits)"
            )
        if len(tracers) > 1:
            raise SEngineError(f"--shards: the network has {len(tracers)} face tracers ({', '.join(tracers)}); one")
        tracer = tracers[0]
        after = {tracer}
        for k in bound.order:  # the tracer and everything downstream of it
            if any(s in after for s, _, _ in incoming[k]):
                after.add(k)
        city_nodes = [k for k in bound.order if k not in after]
        shard_nodes = [k for k in bound.order if k in after and bound.nodes[k].outputs]
        sinks = [k for k in bound.order if k in after and not bound.nodes[k].outputs]
        for k in [*shard_nodes, *sinks]:  # refused before any work: nodes that need the whole city
            why = bound.nodes[k].shard_refusal(frozenset(dp for _, _, dp in incoming[k]))
            if why:
                raise SEngineError(
                    f"--shards: {bound.nodes[k].where} cannot run one enclosure group at a time: {why} "
                    "(run without --shards)"
                )
        for k in sinks:
            if type(bound.nodes[k]).write_shard is SENode.write_shard:
                raise SEngineError(f"--shards: node {k!r} ({bound.nodes[k].name}) cannot write shard by shard")
        can = sorted({f for k in sinks for f in bound.nodes[k].shard_formats})
        bad = sorted(set(formats) - set(can))
        if bad:
            raise ParameterError(
                f"--shards writes {', '.join(can) or 'nothing'}, not {', '.join(bad)} (run without --shards for those)",
                where="--format",
            )
        layers: dict[str, dict[str, Layer]] = {}
        counts: dict[str, int] = {}
        secs: dict[str, float] = {}
        node_areas: dict[str, float] = {}  # stats.json's "areas" ("areas" below are the enclosures)
        report: dict[str, Any] = {}
        n_total = len(city_nodes)
        for i, node_id in enumerate(city_nodes, 1):
            node = bound.nodes[node_id]
            kwargs = {p: None for p in node.inputs}
            for s, sp, dp in incoming[node_id]:
                kwargs[dp] = layers[s][sp]
            t0 = time.perf_counter()
            result = _run_node(node, kwargs, workers)
            dt = time.perf_counter() - t0
            layers[node_id] = dict(result.layers)
            count = node.counted(result.layers)
            if node.outputs and not node.source_for:  # the plan's inputs count no features, but have an area
                counts[node_id] = count
            area = layer_area(result.layers, count)
            if area > 0:
                node_areas[node_id] = round(area, 1)
            secs[node_id] = round(dt, 4)
            if result.report:
                report[node_id] = result.report
            if progress is not None:
                progress(i, n_total + 1, node_id, node.name, counts.get(node_id, 0), dt)
        port = bound.nodes[tracer].shard_port
        src = next((s, sp) for s, sp, dp in incoming[tracer] if dp == port)
        areas = layers[src[0]][src[1]]
        import shapely

        groups = group_enclosures(shapely.area(areas.geometry), shards)
        groups.append(np.zeros(0, np.int64))  # the remainder: faces outside every enclosure
        city_ports = {k: frozenset(dp for s, _, dp in incoming[k] if s not in after) for k in sinks}
        streams = {}  # whole-city layers on stream ports: each feature goes to the shard of its enclosure
        for k in shard_nodes:
            for s, sp, dp in incoming[k]:
                lay = layers[s][sp] if s not in after else None
                if lay is not None and dp in bound.nodes[k].shard_streams:
                    streams[(k, dp)] = containing(shapely.point_on_surface(lay.geometry), areas.geometry)
        _CITY = _City(bound, incoming, layers, shard_nodes, sinks, tracer, groups, city_ports, streams)
        outcomes: list = [None] * len(groups)
        t_shards = time.perf_counter()
        joined = 0  # shards handed to the sinks' join_shard, in order, while the next ones run
        t_join = 0.0
        with make_scheduler(scheduler, workers, len(groups)) as sched:
            done = 0
            shared = None if sched.inherits else _CITY  # a remote cluster's workers get the city once each
            for idx, ok, value in sched.run(_run_shard, range(len(groups)), shared=shared):
                if not ok:
                    raise value
                outcomes[idx] = value
                done += 1
                log.info("shard %d/%d: %s in %.2f s", done, len(groups), value["counts"], value["total"])
                while joined < len(groups) and outcomes[joined] is not None:
                    t = time.perf_counter()
                    for node_id in sinks:
                        bound.nodes[node_id].join_shard(outcomes[joined]["parts"][node_id], shard=joined)
                    t_join += time.perf_counter() - t
                    joined += 1
        shard_wall = time.perf_counter() - t_shards
        for node_id in shard_nodes:
            counts[node_id] = int(sum(o["counts"].get(node_id, 0) for o in outcomes))
            area = sum(o["areas"].get(node_id, 0.0) for o in outcomes)
            if area > 0:
                node_areas[node_id] = round(area, 1)
            secs[node_id] = round(sum(o["seconds"].get(node_id, 0.0) for o in outcomes), 4)
            reps = [o["reports"][node_id] for o in outcomes if node_id in o["reports"]]
            if reps:
                report[node_id] = merge_reports(reps)
        t_finish = time.perf_counter()
        for node_id in sinks:
            node = bound.nodes[node_id]
            kwargs = {p: None for p in node.inputs}
            for s, sp, dp in incoming[node_id]:
                if s not in after:
                    kwargs[dp] = layers[s][sp]
            t0 = time.perf_counter()
            rep = node.finish_shards(kwargs, [o["parts"][node_id] for o in outcomes], city_ports=city_ports[node_id])
            secs[node_id] = round(sum(o["seconds"].get(node_id, 0.0) for o in outcomes) + time.perf_counter() - t0, 4)
            if rep:
                report[node_id] = rep
        t_finish = time.perf_counter() - t_finish
        if progress is not None:
            progress(n_total + 1, n_total + 1, "shards", f"{len(groups)} shards", counts.get(tracer, 0), shard_wall)
        secs["shards"] = round(shard_wall, 4)
        secs["join"] = round(t_join + t_finish, 4)
        secs["total"] = round(time.perf_counter() - t_start, 4)
        stats = {
            "sengine": __version__,
            "config": net.source,
            "seed": seed,
            "shards": len(groups),
            "counts": counts,
            "areas": node_areas,
            "seconds": secs,
            "report": report,
        }
        parts_dir = tmp / ".parts"
        if parts_dir.exists():
            shutil.rmtree(parts_dir)
        _write_json(tmp / "stats.json", stats)
        _move_into(tmp, out_dir)
        return Result(layers, stats)
    finally:
        _CITY = None
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
