"""Batch synthesis: one city per variant, resumable, on any scheduler.

``sengine batch CONFIG -o OUT`` runs a configuration once per variant
(:mod:`sengine.variants`) into ``OUT/<variant id>/`` and keeps a table of
them:

* ``OUT/batch.csv``: one row per variant, appended as variants finish and
  rewritten in the batch's order at the end: its id and inputs (seed, map
  files, parameter values), feature counts per node (``n_<node>``), the
  planning figures of the run's report (``far``, ``coverage``, ``gfa_m2``,
  ``residents``), seconds and the inputs' hash; ``OUT/batch.parquet`` holds
  the same when pyarrow is installed;
* ``OUT/contact.png``: every variant's preview side by side (:mod:`sengine.contact`).

Crash safety.  A variant is made in a temporary folder (``OUT/.<id>.*.tmp``)
and renamed to ``OUT/<id>`` when complete, with ``variant.json`` holding the
hash of its inputs (the effective network, the map files' contents, the seed,
the formats and sengine's version).  A rerun skips a variant whose folder
holds the same hash, redoes missing or changed ones, and first removes the
temporary folders a killed run left (``force=True`` redoes all).  The code
of the nodes is not hashed, nor files named by node parameters (only the
plan's maps are read): after changing a plugin, use ``force``.  SIGINT and
SIGTERM kill every worker, remove the partial variants, keep the finished
ones and the table, and raise :class:`BatchInterrupted` saying how many
finished.  Two batches cannot write into one folder at once (a lock file).

Every variant runs the same code on any scheduler (:mod:`sengine.scheduler`),
with one worker inside a pool or a Dask task, so the same variant gives the
same bytes under ``local``, ``dask`` and any ``--workers``.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import logging
import os
import re
import shutil
import signal
import threading
import time
import uuid
from collections.abc import Callable, Iterable, Sequence
from contextlib import contextmanager, suppress
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from . import __version__
from .errors import SEngineError
from .plan import MapSpec
from .variants import Variant

__all__ = ["BatchSpec", "BatchReport", "BatchInterrupted", "run_batch", "run_variant", "build_network"]

log = logging.getLogger(__name__)

FIGURES = (("far", "far"), ("coverage", "coverage"), ("gfa_m2", "floor_area_m2"), ("residents", "residents"))
_TEMP = re.compile(r"^\..+\.tmp$")  # OUT/.<anything>.tmp: a variant in the making, or one being replaced


class BatchInterrupted(KeyboardInterrupt):
    """SIGINT or SIGTERM stopped a batch; ``finished`` of ``total`` variants are in the output folder."""

    def __init__(self, signum: int, finished: int = 0, total: int = 0, out: Path | None = None):
        super().__init__(signum)
        self.signum, self.finished, self.total, self.out = signum, finished, total, out

    def __str__(self) -> str:
        return f"interrupted: {self.finished} of {self.total} variants finished in {self.out}"


@dataclass(frozen=True)
class BatchSpec:
    """What every variant of a batch shares (picklable: it travels with each task)."""

    config: str
    out: str
    plugins: tuple[str, ...] = ()
    fixed_maps: tuple[str, ...] = ()
    fixed_sets: tuple[str, ...] = ()
    formats: tuple[str, ...] = ()
    options: tuple[tuple[str, str], ...] = ()  # the exporters' options (--crs, --origin), as sorted pairs


@dataclass(frozen=True)
class _Task:
    spec: BatchSpec
    variant: Variant
    digest: str
    workers: int


@dataclass
class BatchReport:
    """What :func:`run_batch` did."""

    out: Path
    variants: list[Variant]
    made: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    failed: dict[str, str] = field(default_factory=dict)
    rows: list[dict] = field(default_factory=list)
    seconds: float = 0.0
    scheduler: str = "local"


# -- the task: one variant ---------------------------------------------------------------------------------------
def build_network(spec: BatchSpec, variant: Variant):
    """The configuration's network with the variant's maps and parameter values (not yet validated)."""
    from .xmlconfig import load_config

    # the variant's maps go in before the plan's source nodes are made (load_config wires them)
    maps = [*spec.fixed_maps, *(MapSpec(kind, Path(path), {}, where) for kind, path, where in variant.maps)]
    net = load_config(spec.config, sets=spec.fixed_sets, maps=maps, plugins=spec.plugins)
    for target, value, where in variant.params:
        node_id, _, name = target.partition(".")
        net.set_param(node_id, name, value, where=where)
    return net


def run_variant(task: _Task) -> dict:
    """Make one variant into ``OUT/<id>``: a temporary folder renamed when complete; return its stats.

    Runs in whatever process the scheduler chose; ``task.workers`` is the
    processes its nodes may use (1 inside a pool or a Dask task).
    """
    out = Path(task.spec.out)
    variant = task.variant
    final = out / variant.id
    part = out / f".{variant.id}.{uuid.uuid4().hex[:8]}.part.tmp"
    try:
        net = build_network(task.spec, variant)
        seed = net.seed if variant.seed is None else variant.seed
        stats = net.run(
            seed=seed, out=part, formats=task.spec.formats, workers=task.workers, options=dict(task.spec.options)
        ).stats
        record = {"id": variant.id, "hash": task.digest, "seed": seed, "inputs": variant.inputs()}
        (part / "variant.json").write_text(json.dumps(record, indent=2) + "\n")
        _install(part, final)
        return stats
    finally:
        if part.exists():
            shutil.rmtree(part, ignore_errors=True)


def _install(part: Path, final: Path) -> None:
    """Rename ``part`` to ``final``; an older ``final`` is moved aside first, then removed."""
    if not final.exists():
        os.replace(part, final)
        return
    old = final.with_name(f".{final.name}.{uuid.uuid4().hex[:8]}.old.tmp")
    os.replace(final, old)
    os.replace(part, final)
    shutil.rmtree(old, ignore_errors=True)


# -- inputs' hash --------------------------------------------------------------------------------------------------
_file_hashes: dict[tuple[str, int, int], str] = {}


def _file_hash(path: Path) -> str:
    try:
        st = path.stat()
    except OSError:
        return "missing"
    key = (str(path), st.st_size, st.st_mtime_ns)
    if key not in _file_hashes:
        h = hashlib.sha256()
        with open(path, "rb") as f:
            for chunk in iter(lambda: f.read(1 << 20), b""):
                h.update(chunk)
        _file_hashes[key] = h.hexdigest()
    return _file_hashes[key]


def network_digest(net, formats: Iterable[str], options=()) -> str:
    """The hash of what makes a network's outputs.

    Nodes, parameters, connections, plan, map contents, formats and the exporters' options.
    """
    plan = net.plan
    doc = {
        "sengine": __version__,
        "nodes": [[s.id, s.type, sorted((k, str(v)) for k, v in s.params.items())] for s in net.specs.values()],
        "connections": [[c.src, c.src_port, c.dst, c.dst_port] for c in net.connections],
        "plan": {
            "name": plan.name,
            "size": list(plan.size),
            "origin": list(plan.origin),
            "attrs": sorted(plan.attrs.items()),
            "rules": [[r.tag, sorted(r.attrs.items())] for r in plan.rules],
            "maps": {k: [_file_hash(Path(m.src)), sorted(m.attrs.items())] for k, m in sorted(plan.maps.items())},
        },
        "formats": sorted(formats),
        **({"options": sorted(options)} if options else {}),
    }
    return hashlib.sha256(json.dumps(doc, sort_keys=True, default=str).encode()).hexdigest()


def _variant_digest(network: str, seed: int) -> str:
    return hashlib.sha256(f"{network}:{seed}".encode()).hexdigest()


# -- the table -----------------------------------------------------------------------------------------------------
def _figures(report: dict) -> dict:
    """The planning figures of a run's report: the first node report holding a ``city`` summary with ``far``."""
    for rep in report.values():
        city = rep.get("city") if isinstance(rep, dict) else None
        if isinstance(city, dict) and "far" in city:
            return {col: city.get(key) for col, key in FIGURES}
    return {col: None for col, _ in FIGURES}


def _columns(variants: Sequence[Variant], count_nodes: Sequence[str]) -> list[str]:
    kinds = list(dict.fromkeys(k for v in variants for k, _, _ in v.maps))
    params = list(dict.fromkeys(t for v in variants for t, _, _ in v.params))
    return [
        "id",
        "seed",
        *kinds,
        *params,
        *(f"n_{n}" for n in count_nodes),
        *(col for col, _ in FIGURES),
        "seconds",
        "inputs_hash",
    ]


def _row(variant: Variant, stats: dict, digest: str, count_nodes: Sequence[str]) -> dict:
    row: dict[str, Any] = {"id": variant.id, "seed": stats.get("seed")}
    row.update({k: p for k, p, _ in variant.maps})
    row.update({t: v for t, v, _ in variant.params})
    counts = stats.get("counts", {})
    row.update({f"n_{n}": counts.get(n) for n in count_nodes})
    row.update(_figures(stats.get("report", {})))
    row["seconds"] = stats.get("seconds", {}).get("total")
    row["inputs_hash"] = digest[:16]
    return row


def _csv_line(columns: Sequence[str], row: dict) -> str:
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(["" if row.get(c) is None else row.get(c) for c in columns])
    return buf.getvalue()


def _write_atomic(path: Path, data: bytes) -> None:
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex[:8]}.tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def _write_tables(out: Path, columns: list[str], rows: list[dict]) -> None:
    """``batch.csv`` in the batch's order, and ``batch.parquet`` when pyarrow is installed and a row is made."""
    text = _csv_line(columns, dict(zip(columns, columns))) + "".join(_csv_line(columns, r) for r in rows)
    _write_atomic(out / "batch.csv", text.encode())
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return
    if not rows:  # no variant made: no table (one left by an earlier run would list variants csv does not)
        (out / "batch.parquet").unlink(missing_ok=True)
        return
    table = pa.table({c: [r.get(c) for r in rows] for c in columns})
    tmp = out / f".batch.parquet.{uuid.uuid4().hex[:8]}.tmp"
    pq.write_table(table, tmp)
    os.replace(tmp, out / "batch.parquet")


def _caption(row: dict) -> str:
    parts = []
    lots = next((row[c] for c in ("n_lots",) if row.get(c) is not None), None)
    if lots is not None:
        parts.append(f"{lots:,} lots")
    if row.get("far") is not None:
        parts.append(f"FAR {row['far']:.2f}")
    if row.get("coverage") is not None:
        parts.append(f"cov {row['coverage']:.2f}")
    if row.get("residents") is not None:
        parts.append(f"{row['residents']:,} res")
    return ", ".join(parts)


def _write_contact(out: Path, rows: list[dict]) -> None:
    from .contact import contact_sheet

    tiles = [(out / r["id"] / "preview.png", r["id"], _caption(r)) for r in rows]
    tmp = out / f".contact.{uuid.uuid4().hex[:8]}.png.tmp"
    contact_sheet(tiles, tmp)
    os.replace(tmp, out / "contact.png")


# -- the output folder -------------------------------------------------------------------------------------------
@contextmanager
def _locked(out: Path):
    """Hold ``OUT/.batch.lock`` (POSIX): a second batch into the same folder is an error, not a mix."""
    try:
        import fcntl
    except ImportError:  # Windows: no lock
        yield
        return
    with open(out / ".batch.lock", "w") as f:
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            raise SEngineError(f"{out}: another sengine batch is writing into this folder") from None
        yield


def _remove_temporaries(out: Path) -> int:
    """Remove what a killed run left: ``OUT/.*.tmp`` files and folders; return how many."""
    n = 0
    for p in out.iterdir():
        if _TEMP.match(p.name):
            if p.is_dir() and not p.is_symlink():
                shutil.rmtree(p, ignore_errors=True)
            else:
                with suppress(OSError):
                    p.unlink()
            n += 1
    return n


def _finished(out: Path, variant: Variant, digest: str) -> dict | None:
    """The stats of a variant already made with these inputs, else None."""
    folder = out / variant.id
    try:
        record = json.loads((folder / "variant.json").read_text())
        if record.get("hash") != digest:
            return None
        return json.loads((folder / "stats.json").read_text())
    except (OSError, ValueError):
        return None


@contextmanager
def _signals_interrupt():
    """SIGTERM (and SIGINT) raise :class:`BatchInterrupted` here, in the main thread; restored afterwards."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        raise BatchInterrupted(signum)

    old = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)


@contextmanager
def _signals_ignored():
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {s: signal.signal(s, signal.SIG_IGN) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)


# -- the batch -----------------------------------------------------------------------------------------------------
def run_batch(
    spec: BatchSpec,
    variants: list[Variant],
    *,
    scheduler: str = "local",
    workers: int = 1,
    force: bool = False,
    on_done: Callable[[int, int, dict], None] | None = None,
    on_failed: Callable[[Variant, BaseException], None] | None = None,
    on_start: Callable[[int, str], None] | None = None,
) -> BatchReport:
    """Make every variant into ``spec.out``; skip the ones already made with the same inputs.

    Parameters
    ----------
    spec : BatchSpec
        The configuration (absolute path), output folder and what every variant shares.
    variants : list of Variant
        From :func:`sengine.variants.plan_variants`.
    scheduler : str
        ``local``, ``dask`` or ``tcp://HOST:PORT`` (:func:`sengine.scheduler.make_scheduler`).
    workers : int
        Processes (local) or LocalCluster workers (dask).
    force : bool
        Make every variant again.
    on_done, on_failed : callable, optional
        Called in this process as ``on_done(k, n, row)`` for each variant made
        (k of the n to make), ``on_failed(variant, error)`` for each that failed.
    on_start : callable, optional
        Called in this process as ``on_start(n, scheduler)`` once the ``n``
        variants to make (those not already made) are handed to the
        scheduler (a progress display's total).

    Returns
    -------
    BatchReport
        A variant that failed is listed in ``failed`` (and has no folder);
        the others are made.

    Raises
    ------
    SEngineError
        A variant's network does not validate (before anything is written).
    BatchInterrupted
        SIGINT or SIGTERM: every worker is stopped, the finished variants
        and the table stay, nothing partial does.
    """
    from .scheduler import check_scheduler, make_scheduler

    t0 = time.perf_counter()
    scheduler = check_scheduler(scheduler)
    out = Path(spec.out)
    report = BatchReport(out, variants, scheduler=scheduler)
    # check every variant's network before writing anything
    digests: dict[str, str] = {}
    networks: dict[tuple, tuple[str, int]] = {}  # (maps, params) -> (network hash, configuration seed)
    count_nodes: list[str] = []
    for v in variants:
        key = (v.maps, v.params)
        if key not in networks:
            net = build_network(spec, v)
            bound = net.validate()
            if not count_nodes:
                count_nodes = [n for n in bound.order if bound.nodes[n].outputs]
            networks[key] = (network_digest(net, spec.formats, spec.options), net.seed)
        net_digest, config_seed = networks[key]
        digests[v.id] = _variant_digest(net_digest, config_seed if v.seed is None else v.seed)
    columns = _columns(variants, count_nodes)
    out.mkdir(parents=True, exist_ok=True)
    with _locked(out):
        removed = _remove_temporaries(out)
        if removed:
            log.info("removed %d temporary folders a killed run left in %s", removed, out)
        done: dict[str, dict] = {}
        todo: list[Variant] = []
        for v in variants:
            stats = None if force else _finished(out, v, digests[v.id])
            if stats is None:
                todo.append(v)
            else:
                done[v.id] = _row(v, stats, digests[v.id], count_nodes)
                report.skipped.append(v.id)
        _write_tables(out, columns, [done[v.id] for v in variants if v.id in done])
        sched = None
        try:
            with _signals_interrupt():
                if todo:
                    sched = make_scheduler(scheduler, workers, len(todo))
                    report.scheduler = sched.name
                    tasks = [_Task(spec, v, digests[v.id], sched.task_workers) for v in todo]
                    if on_start is not None:
                        on_start(len(todo), sched.name)
                    with sched, open(out / "batch.csv", "a", newline="") as table:
                        for i, ok, value in sched.run(run_variant, tasks):
                            v = todo[i]
                            if ok:
                                row = _row(v, value, digests[v.id], count_nodes)
                                done[v.id] = row
                                report.made.append(v.id)
                                table.write(_csv_line(columns, row))
                                table.flush()
                                if on_done is not None:
                                    on_done(len(report.made), len(todo), row)
                            else:
                                log.debug("variant %s failed", v.id, exc_info=value)
                                report.failed[v.id] = _one_line(value)
                                if on_failed is not None:
                                    on_failed(v, value)
        except BatchInterrupted as stop:
            with _signals_ignored():  # a second Ctrl-C does not cut the clean-up short
                if sched is not None:
                    sched.stop()
                _remove_temporaries(out)
                for v in todo:  # finished by a worker before this process heard of it
                    stats = _finished(out, v, digests[v.id]) if v.id not in done else None
                    if stats is not None:
                        done[v.id] = _row(v, stats, digests[v.id], count_nodes)
                report.rows = [done[v.id] for v in variants if v.id in done]
                _write_tables(out, columns, report.rows)
                _write_contact(out, report.rows)
            raise BatchInterrupted(stop.signum, len(report.rows), len(variants), out) from None
        report.rows = [done[v.id] for v in variants if v.id in done]
        _write_tables(out, columns, report.rows)
        _write_contact(out, report.rows)
    report.seconds = round(time.perf_counter() - t0, 3)
    return report


def _one_line(exc: BaseException) -> str:
    text = str(exc) if isinstance(exc, SEngineError) else f"{type(exc).__name__}: {exc}"
    return " ".join(text.split())
