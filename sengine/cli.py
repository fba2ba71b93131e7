"""The ``sengine`` command: run | batch | validate | nodes | graph | osm | view.

A user mistake prints one line (``sengine: error: WHERE: WHAT``) and exits
with status 2; ``--debug`` shows the traceback instead.
"""

from __future__ import annotations

import argparse
import json
import logging
import signal
import sys
import tempfile
import threading
import warnings
from collections.abc import Sequence
from pathlib import Path

from . import __version__, registry
from .errors import LimitError, OutputError, Problems, SEngineError, SEngineWarning
from .parallel import available_cores
from .plan import MapSpec

log = logging.getLogger("sengine")

EXIT_USER_ERROR = 2


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line, like every other error (exit status 2)."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--plugin",
        action="append",
        default=[],
        metavar="P",
        help="load a plugin module or .py path before reading the config (repeatable)",
    )
    p.add_argument("--debug", action="store_true", help="show tracebacks")
    p.add_argument("--quiet", "-q", action="store_true", help="no progress on stderr")


def _run_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("-o", "--out", required=True, type=Path, help="output folder")
    p.add_argument("--seed", type=int, help="network seed (overrides the config's)")
    p.add_argument(
        "--set",
        dest="sets",
        action="append",
        default=[],
        metavar="NODE.PARAM=VALUE",
        help="set a node parameter (repeatable)",
    )
    p.add_argument(
        "--workers",
        type=_workers,
        default=available_cores(),
        metavar="N",
        help="worker processes: chunks of nodes that map features one by one, exporters' files, "
        "batch seeds (default: every core, %(default)s here; the result is the same for any N)",
    )
    p.add_argument(
        "--format",
        dest="formats",
        default="",
        help="comma list of outputs: glb,geojson,osm,png,obj,cityjson,gpkg,parquet,html "
        "(default: the exporter's, glb,geojson,osm,png,html for export.city)",
    )
    p.add_argument(
        "--crs",
        type=_crs,
        default=None,
        metavar="CRS",
        help="frame of the vector outputs: utm (the city's projected frame), wgs84 or EPSG:n "
        "(default: utm for gpkg and parquet, wgs84 for geojson as RFC 7946 asks)",
    )
    p.add_argument(
        "--origin",
        choices=("local", "geo"),
        default="local",
        help="3D outputs (glb, obj) around the city's origin (local, the default) or in the planar frame's "
        "own coordinates (geo: UTM for an OSM city); the origin is kept as metadata",
    )
    p.add_argument(
        "--lod",
        type=int,
        choices=(1, 2),
        help="buildings in glb, obj and cityjson: 1 flat-roofed boxes, 2 with roofs (sets every export.city's lod)",
    )


def build_parser() -> argparse.ArgumentParser:
    """The ``sengine`` argument parser with its six commands."""
    parser = _Parser(prog="sengine", description="A procedural city engine after skylineEngine.")
    parser.add_argument("--version", action="version", version=f"sengine {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("run", help="run a city config and write its outputs")
    p.add_argument("config", type=Path)
    _run_options(p)
    p.add_argument(
        "--map",
        dest="maps",
        action="append",
        default=[],
        metavar="KIND=PATH",
        help="replace the config's map of a kind (district, landuse, height, osm ...)",
    )
    p.add_argument(
        "--check",
        action="store_true",
        help="exit with status 1 and a one-line summary when a node reports violations (e.g. buildings.check)",
    )
    p.add_argument(
        "--scale",
        type=_scale,
        default=None,
        metavar="F",
        help="a synthetic city F times as large in area: its maps stretched over the size times sqrt(F) "
        "(configs/metropolis.xml --scale 0.1 is a tenth of it)",
    )
    p.add_argument(
        "--shards",
        type=_workers,
        default=None,
        metavar="N",
        help="split the city into about N shards along its major-road enclosures, run them on --workers "
        "processes and write the layers shard by shard (bounded memory; the same files as unsharded; "
        "formats parquet, gpkg and glb, which is then one city-<shard>.glb per shard)",
    )
    p.add_argument(
        "--scheduler",
        default="local",
        metavar="local|dask|tcp://HOST:PORT",
        help="with --shards: where the shards run, local processes (default), a Dask LocalCluster of "
        "--workers processes, or an existing Dask cluster (pip install 'sengine[dask]'; its workers "
        "must see the output folder's path)",
    )
    _common(p)

    p = sub.add_parser(
        "batch",
        help="one city per variant (seeds, map sets, parameter sweeps, a manifest) into OUT/<id>, resumable",
        description="Variants multiply: --seeds x --maps stems x --set sweeps x --manifest rows. Each goes to "
        "OUT/<variant id>/; OUT/batch.csv (and batch.parquet with pyarrow) has one row per variant and "
        "OUT/contact.png their previews side by side. A rerun skips the variants already made with the same "
        "inputs (--force redoes them).",
    )
    p.add_argument("config", type=Path)
    _run_options(p)
    p.add_argument(
        "--seeds", help="seeds as a list or ranges, e.g. 1,2,5 or 1-10 (default: the config's seed, or --seed)"
    )
    p.add_argument(
        "--maps",
        nargs="+",
        default=[],
        metavar="KIND=PATTERN",
        help="image-map sets, e.g. landuse='maps/lu/*.png' height='maps/h/*.png': one variant per file stem, "
        "the kinds' files paired by stem",
    )
    p.add_argument(
        "--manifest",
        type=Path,
        help="CSV with one variant per row: columns id, seed, NODE.PARAM (a value) and map kinds "
        "(a path relative to the CSV); an empty cell keeps the config's",
    )
    p.add_argument(
        "--map",
        dest="fixed_maps",
        action="append",
        default=[],
        metavar="KIND=PATH",
        help="replace the config's map of a kind in every variant",
    )
    p.add_argument(
        "--scheduler",
        default="local",
        metavar="local|dask|tcp://HOST:PORT",
        help="where variants run: local processes (default), a Dask LocalCluster of --workers processes, or an "
        "existing Dask cluster (needs pip install 'sengine[dask]'; its workers must see the same paths)",
    )
    p.add_argument("--force", action="store_true", help="make every variant again, even those already made")
    _common(p)
    p.epilog = (
        "--set NODE.PARAM=v1,v2,v3 sweeps the values (one variant each); write a value holding commas with "
        "spaces instead, or put it in a manifest."
    )

    p = sub.add_parser("osm", help="one command from an OpenStreetMap file to a city")
    p.add_argument("file", type=Path, help=".osm, .osm.bz2 or .osm.pbf")
    _run_options(p)
    _common(p)

    p = sub.add_parser("validate", help="check a config without running it")
    p.add_argument("config", type=Path)
    p.add_argument("--set", dest="sets", action="append", default=[], metavar="NODE.PARAM=VALUE")
    p.add_argument("--map", dest="maps", action="append", default=[], metavar="KIND=PATH")
    _common(p)

    p = sub.add_parser("nodes", help="list every registered node with its ports and parameters")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.add_argument("--check", action="store_true", help="also list plugins that failed to load")
    p.add_argument(
        "--all", action="store_true", help="with --json: also the rule attributes, map kinds, layer kinds, formats"
    )
    _common(p)

    p = sub.add_parser("view", help="write OUT/index.html, the city in 3D in a browser (--serve: on localhost)")
    p.add_argument("out", type=Path, help="an output folder of a run that wrote html (a default format)")
    p.add_argument("--serve", action="store_true", help="serve the folder on 127.0.0.1 until Ctrl-C")
    p.add_argument("--port", type=_port, default=0, help="port for --serve (default: a free one)")
    _common(p)

    p = sub.add_parser("graph", help="draw a config's network (.dot, .svg or .png)")
    p.add_argument("config", type=Path)
    p.add_argument("-o", "--out", required=True, type=Path, help="output file: .dot, .svg or .png")
    _common(p)
    return parser


def _progress(args: argparse.Namespace):
    """A progress display on stderr when it is a terminal and ``--quiet`` is not given."""
    if args.quiet or not sys.stderr.isatty():
        return None
    from .progress import TerminalProgress

    return TerminalProgress(sys.stderr)


def _formats(text: str) -> frozenset[str]:
    """``--format``: formats some node writes (:func:`sengine.registry.check_formats`), or an error."""
    return registry.check_formats(text.split(","))


def _crs(text: str) -> str:
    """``--crs``: utm, wgs84 or EPSG:n."""
    from .geom.crs import parse_crs_option

    try:
        return parse_crs_option(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def _options(args: argparse.Namespace) -> dict:
    """The exporters' options of a run command (``--crs``, ``--origin``)."""
    return {"crs": args.crs, "origin": args.origin}


def _port(text: str) -> int:
    """``--port``: 0 (a free one) to 65535."""
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if not 0 <= n <= 65535:
        raise argparse.ArgumentTypeError(f"{n} is not a port (0 to 65535)")
    return n


def _workers(text: str) -> int:
    """``--workers``: a whole number of processes, at least 1."""
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if n < 1:
        raise argparse.ArgumentTypeError(f"{n} is less than 1")
    return n


def _scale(text: str) -> float:
    """``--scale``: a positive area factor."""
    try:
        f = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (f > 0 and f < float("inf")):
        raise argparse.ArgumentTypeError(f"{text!r} must be a positive number")
    return f


def _apply_scale(net, factor: float | None) -> None:
    """``--scale F``: the city's size times sqrt(F), its maps stretched over it; absurd sizes refused."""
    if factor is None:
        return
    plan = net.plan
    if any(spec.kind == "osm" for spec in plan.maps.values()):
        raise SEngineError("--scale stretches a synthetic city's image maps; an OSM city has the size of its data")
    from .xmlconfig import MAX_CITY_SIZE

    k = factor**0.5
    w, h = (float(v) * k for v in plan.size)
    if max(w, h) > MAX_CITY_SIZE:
        raise LimitError(
            f"--scale {factor:g} makes the city {w / 1000:,.0f} x {h / 1000:,.0f} km, {factor:,.3g} times its "
            f"area; the limit is {MAX_CITY_SIZE / 1000:,.0f} km a side",
            where="--scale",
        )
    plan.size = (round(w, 3), round(h, 3))


MAX_SEEDS = 10_000  # runs in one batch; more is a typo (1-1000000000) or a job for a cluster


def _seeds(text: str) -> list[int]:
    """``--seeds``: a list or ranges of whole numbers, at most MAX_SEEDS of them, refused before any run."""
    spans: list[tuple[int, int]] = []
    for part in text.split(","):
        a, dash, b = part.strip().partition("-")
        try:
            lo, hi = (int(a), int(b)) if dash else (int(a), int(a))
        except ValueError:
            raise SEngineError(f"--seeds {text!r} must be numbers or ranges like 1-10") from None
        if hi < lo:
            raise SEngineError(f"--seeds {text!r}: the range {lo}-{hi} is empty")
        spans.append((lo, hi))
    total = sum(hi - lo + 1 for lo, hi in spans)
    if total > MAX_SEEDS:
        raise LimitError(f"--seeds {text!r} asks for {total:,} runs; the limit is {MAX_SEEDS:,} per batch")
    return [s for lo, hi in spans for s in range(lo, hi + 1)]


def _set_lod(net, lod: int | None) -> None:
    """``--lod``: the ``lod`` parameter of every ``export.city`` node."""
    if lod is not None:
        for spec in net.specs.values():
            if spec.type == "export.city":
                net.set_param(spec.id, "lod", lod, where="--lod")


def cmd_run(args: argparse.Namespace) -> int:
    """``sengine run``: read a config, run it into ``--out``."""
    from .xmlconfig import load_config

    formats = _formats(args.formats)
    net = load_config(args.config, sets=args.sets, maps=args.maps, plugins=args.plugin, seed=args.seed)
    _set_lod(net, args.lod)
    _apply_scale(net, args.scale)
    if args.shards is not None:
        from .shard import run_sharded

        if not args.debug:  # Dask's logs (its loggers set their own levels, in every worker) only with --debug
            for handler in logging.getLogger().handlers:
                handler.addFilter(_no_dask_info)

        result = run_sharded(
            net,
            out=args.out,
            shards=args.shards,
            formats=formats,
            progress=_progress(args),
            workers=args.workers,
            options=_options(args),
            scheduler=args.scheduler,
        )
    else:
        result = _run_network(net, args, formats)
    _print_counts(args, result)
    if args.check:
        return _check(result.stats.get("report", {}))
    return 0


def _run_network(net, args: argparse.Namespace, formats):
    """``net.run`` with the options ``run`` and ``osm`` share."""
    return net.run(
        out=args.out,
        formats=formats,
        progress=_progress(args),
        workers=args.workers,
        options=_options(args),
        check_kinds=args.debug,
    )


def _print_counts(args: argparse.Namespace, result) -> None:
    """The one line a run prints: its counts and seconds (nothing with ``--quiet``)."""
    if not args.quiet:
        counts = ", ".join(f"{k} {v:,}" for k, v in result.stats["counts"].items())
        print(f"{args.out}: {counts} in {result.stats['seconds']['total']:.2f} s")


def _check(reports: dict) -> int:
    """1 and one line on stderr when any node's report counts ``violations`` (its ``summary`` says what), else 0."""
    found = [
        (node, rep) for node, rep in reports.items() if isinstance(rep, dict) and int(rep.get("violations", 0) or 0) > 0
    ]
    if not found:
        return 0
    text = "; ".join(f"{node}: {rep.get('summary') or str(rep['violations']) + ' violations'}" for node, rep in found)
    print(f"sengine: check failed: {text}", file=sys.stderr)
    return 1


def cmd_batch(args: argparse.Namespace) -> int:
    """One city per variant, on the chosen scheduler; see :mod:`sengine.batch`."""
    from .batch import BatchInterrupted, BatchSpec, run_batch
    from .network import check_output_folder
    from .variants import pair_maps, parse_seeds, parse_sweeps, plan_variants, read_manifest

    if args.seeds is not None and args.seed is not None:
        raise SEngineError("give --seeds or --seed, not both")
    seeds_text = args.seeds if args.seeds is not None else (str(args.seed) if args.seed is not None else None)
    seeds = parse_seeds(seeds_text) if seeds_text is not None else None
    map_sets = pair_maps(args.maps)
    fixed_sets, sweeps = parse_sweeps(args.sets)
    manifest = read_manifest(args.manifest) if args.manifest is not None else None
    plugins = tuple(str(Path(p).resolve()) if p.endswith(".py") or "/" in p else p for p in args.plugin)
    fixed_maps = []
    for item in args.fixed_maps:
        kind, sep, src = item.partition("=")
        if not sep or not kind or not src:
            raise SEngineError(f"--map {item!r} must be KIND=PATH")
        fixed_maps.append(f"{kind}={Path(src).resolve()}")
    check_output_folder(args.out)  # before any work: a file, under a file, unwritable
    if args.lod is not None:  # --lod: the lod of every export.city node, for every variant
        from .xmlconfig import load_config

        base = load_config(args.config, plugins=plugins)
        fixed_sets = [
            *fixed_sets,
            *(f"{sp.id}.lod={args.lod}" for sp in base.specs.values() if sp.type == "export.city"),
        ]
    spec = BatchSpec(
        config=str(args.config.resolve()),
        out=str(args.out.resolve()),
        plugins=plugins,
        fixed_maps=tuple(fixed_maps),
        fixed_sets=tuple(fixed_sets),
        formats=tuple(sorted(_formats(args.formats))),
        options=tuple(sorted((k, str(v)) for k, v in _options(args).items() if v is not None)),
    )
    from .xmlconfig import load_config

    config_seed = load_config(args.config, plugins=plugins).seed
    variants = plan_variants(
        config_seed=config_seed,
        seeds=seeds,
        map_sets=map_sets,
        sweeps=sweeps,
        manifest=manifest,
        fixed_maps=spec.fixed_maps,
        fixed_sets=spec.fixed_sets,
    )

    # on a terminal, one bar over the variants (count, rate, time left) with a line above it for each variant;
    # the variants' own runs draw nothing (they may run in other processes): the two never draw over each other
    display = _progress(args)
    tally = {"done": 0, "total": 0}

    def started(n: int, scheduler: str) -> None:
        tally["total"] = n
        if display is not None:
            display.begin(f"batch: {n} variant{'' if n == 1 else 's'} ({scheduler})")
            display.advance(0, n, "variants")

    def say(line: str, file=None) -> None:
        if display is not None:
            display.write(line, file or sys.stdout)
            tally["done"] += 1
            display.advance(tally["done"], tally["total"], "variants")
        else:
            print(line, file=file or sys.stdout, flush=True)

    def done(k: int, n: int, row: dict) -> None:
        if not args.quiet:
            counts = ", ".join(f"{c[2:]} {row[c]:,}" for c in row if c.startswith("n_") and row[c] is not None)
            far = f", FAR {row['far']:.2f}" if row.get("far") is not None else ""
            say(f"[{k}/{n}] {row['id']}: {counts}{far} in {row['seconds']:.1f} s")

    def failed(variant, exc: BaseException) -> None:
        say(f"sengine: error: variant {variant.id}: {_one_line(str(exc))}", sys.stderr)

    if not args.debug:  # Dask's logs (its loggers set their own levels, in every worker) only with --debug
        for handler in logging.getLogger().handlers:
            handler.addFilter(_no_dask_info)
    try:
        report = run_batch(
            spec,
            variants,
            scheduler=args.scheduler,
            workers=args.workers,
            force=args.force,
            on_done=done,
            on_failed=failed,
            on_start=started,
        )
    except BatchInterrupted as stop:
        if display is not None:
            display.close()
        print(f"sengine: {stop}", file=sys.stderr)
        return 128 + int(stop.signum)
    finally:
        if display is not None:
            display.close()
    if not args.quiet:
        made = len(report.made)
        already = f", {len(report.skipped)} already made" if report.skipped else ""
        print(
            f"{args.out}: {made} variant{'' if made == 1 else 's'} made{already} in {report.seconds:.1f} s "
            f"({report.scheduler}); batch.csv, contact.png"
        )
    if report.failed:
        ids = list(report.failed)
        named = ", ".join(ids[:5]) + (f" and {len(ids) - 5} more" if len(ids) > 5 else "")
        raise SEngineError(f"{len(ids)} of {len(variants)} variants failed ({named}); a rerun retries them")
    return 0


def _no_dask_info(record: logging.LogRecord) -> bool:
    """Dask's records below CRITICAL: a failed variant is reported in one line, the rest is noise here."""
    return record.levelno >= logging.CRITICAL or not record.name.startswith(("distributed", "dask"))


def cmd_osm(args: argparse.Namespace) -> int:
    """Run ``networks/loadmap.xml`` on one OSM file with default parameters."""
    from .xmlconfig import load_config

    formats = _formats(args.formats)
    if not args.file.exists():
        raise SEngineError(f"{args.file}: file not found")
    with tempfile.TemporaryDirectory() as tmp:
        config = Path(tmp) / "osm.xml"
        config.write_text(
            f'<sengine version="1">\n  <city name="{_xml_attr(args.file.name)}"/>\n'
            '  <network base="loadmap"/>\n</sengine>\n'
        )
        # errors about the file name the command, not the temporary config
        osm = MapSpec("osm", args.file.resolve(), {}, where="sengine osm")
        net = load_config(config, sets=args.sets, maps=[osm], plugins=args.plugin, seed=args.seed)
        _set_lod(net, args.lod)
        net.source = str(args.file)
        result = _run_network(net, args, formats)
    _print_counts(args, result)
    return 0


def _xml_attr(text: str) -> str:
    return text.replace("&", "&amp;").replace('"', "&quot;").replace("<", "&lt;")


def cmd_validate(args: argparse.Namespace) -> int:
    """``sengine validate``: every check that needs no geometry, every problem at once."""
    from .xmlconfig import load_config

    net = load_config(args.config, sets=args.sets, maps=args.maps, plugins=args.plugin)
    net.check()  # the network, then every input the plan names: files, images, colours
    bound = net.validate()
    print(f"{args.config}: valid, {len(bound.nodes)} nodes, {len(bound.edges)} connections")
    return 0


def _param_line(name: str, p: dict, unset: str = "required") -> str:
    bounds = ""
    if p["min"] is not None or p["max"] is not None:
        bounds = f" [{'' if p['min'] is None else p['min']}, {'' if p['max'] is None else p['max']}]"
    if p["choices"]:
        bounds = f" {{{', '.join(p['choices'])}}}"
    unit = f" {p['unit']}" if p["unit"] else ""
    default = unset if p["default"] is None else repr(p["default"])
    return f"    - {name}: {p['type']} = {default}{unit}{bounds}  {p['doc']}"


def cmd_nodes(args: argparse.Namespace) -> int:
    """List every registered node, then the plan's rule attributes, map kinds, layer kinds and output formats."""
    from . import registry

    for spec in args.plugin:
        registry.load_plugin(spec, base_dir=Path.cwd(), where=f"--plugin {spec}")
    registry.load_all()  # every module of the lazily declared libraries: a broken one is a warning
    described = [registry.get(name).describe() for name in registry.names()]
    rules = {tag: [p.describe(k) for k, p in decl.items()] for tag, decl in sorted(registry.RULES.items())}
    kinds = {
        k: {c: {"dtype": d, "required": r, "doc": doc} for c, (d, r, doc) in cols.items()}
        for k, cols in sorted(registry.kinds().items())
    }
    maps = {k: {"port_kind": pk, "doc": doc} for k, (pk, doc) in sorted(registry.map_kinds().items())}
    formats = dict(sorted(registry.formats().items()))
    if args.json:
        if args.all:
            print(json.dumps({"nodes": described, "rules": rules, "kinds": kinds, "maps": maps, "formats": formats}))
        else:
            print(json.dumps(described, indent=2))
    else:
        for d in described:
            ins = ", ".join(f"{p['name']}:{p['kind']}{'' if p['required'] else '?'}" for p in d["inputs"])
            outs = ", ".join(f"{p['name']}:{p['kind']}" for p in d["outputs"])
            print(f"{d['name']}  ({ins}) -> ({outs})")
            if d["doc"]:
                print(f"    {d['doc']}")
            for p in d["params"]:
                print(_param_line(p["name"], p))
        for tag, params in rules.items():
            print(f"<{tag}> attributes of the plan")
            for p in params:
                print(_param_line(p["name"], p, unset="unset"))
        print("<map kind=...> of the plan")
        for k, m in maps.items():
            print(f"    - {k} (port {k}_map:{m['port_kind']})  {m['doc']}")
        print("layer kinds (required columns*)")
        for k, cols in kinds.items():
            listed = ", ".join(f"{c}{'*' if v['required'] else ''}:{v['dtype']}" for c, v in cols.items())
            print(f"    - {k}: {listed}")
        print("--format")
        for k, doc in formats.items():
            print(f"    - {k}  {doc}")
    if args.check:
        broken = registry.broken_plugins()
        for name, why in broken.items():
            print(f"broken plugin {name}: {why}", file=sys.stderr)
        return 1 if broken else 0
    return 0


def cmd_view(args: argparse.Namespace) -> int:
    """(Re)write the page of an output folder (the viewer of this sengine) and serve it with ``--serve``."""
    from . import viewer

    out = args.out
    if not out.is_dir():
        raise SEngineError(f"{out}: no such output folder")
    if not (out / viewer.DATA_FILE).is_file():
        raise SEngineError(
            f"{out}: holds no {viewer.DATA_FILE} (the city for the page): run sengine again with --format html"
            " (or with html among the --format list)"
        )
    try:
        page = viewer.write_page(out)
    except OSError as err:
        raise SEngineError(f"{out}: cannot write the page: {err.strerror or err}") from None
    if not args.serve:
        print(page.resolve().as_uri())
        return 0
    server = viewer.serve(out, port=args.port)
    host, port = server.server_address[:2]
    print(f"serving {out} on http://{host}:{port}/ (Ctrl-C to stop)", flush=True)
    try:
        threading.Event().wait()
    finally:
        server.shutdown()
        server.server_close()
    return 0


def cmd_graph(args: argparse.Namespace) -> int:
    """``sengine graph``: draw a config's network, the plan's inputs included."""
    from .graphview import write_graph
    from .xmlconfig import load_config

    net = load_config(args.config, plugins=args.plugin)
    try:
        write_graph(net, args.out)
    except OSError as exc:
        raise OutputError(f"cannot write {str(args.out)!r}: {exc.strerror or type(exc).__name__}") from None
    if not args.quiet:
        print(f"wrote {args.out}")
    return 0


COMMANDS = {
    "run": cmd_run,
    "batch": cmd_batch,
    "osm": cmd_osm,
    "validate": cmd_validate,
    "nodes": cmd_nodes,
    "graph": cmd_graph,
    "view": cmd_view,
}


def main(argv: Sequence[str] | None = None) -> int:
    """Run one ``sengine`` command; return the exit status (0, 1 for ``nodes --check``, 2 user error, 130)."""
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as done:  # --help, --version, or a usage error already printed
        return int(done.code or 0)
    logging.basicConfig(
        level=logging.DEBUG if args.debug else logging.WARNING, format="sengine: %(levelname)s: %(message)s"
    )
    old_term = _on_sigterm()
    try:
        with warnings.catch_warnings():
            if not args.debug:  # the libraries' warnings (Pillow, numpy, trimesh ...) are not the user's business
                warnings.simplefilter("ignore")
                warnings.simplefilter("default", SEngineWarning)
                warnings.showwarning = _show_warning
            return COMMANDS[args.command](args)
    except SEngineError as err:
        if args.debug:
            raise
        lines = err.lines if isinstance(err, Problems) else [str(err)]
        print(f"sengine: error: {_one_line(lines[0])}", file=sys.stderr)
        for line in lines[1:]:
            print(f"  {_one_line(line)}", file=sys.stderr)
        return EXIT_USER_ERROR
    except Terminated:
        print("sengine: terminated", file=sys.stderr)
        return 143
    except KeyboardInterrupt:
        print("sengine: interrupted", file=sys.stderr)
        return 130
    finally:
        if old_term is not None:
            signal.signal(signal.SIGTERM, old_term)


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised like Ctrl-C so that the run cleans up (worker processes, the temporary folder)."""


def _raise_terminated(signum, frame):
    raise Terminated()


def _on_sigterm():
    """Make SIGTERM end the run like Ctrl-C; return the handler it replaced (None off the main thread)."""
    try:
        return signal.signal(signal.SIGTERM, _raise_terminated)
    except ValueError:  # not the main thread (a library caller): leave signals alone
        return None


def _show_warning(message, category, filename, lineno, file=None, line=None):
    print(f"sengine: warning: {_one_line(str(message))}", file=sys.stderr)


def _one_line(text: str) -> str:
    return " ".join(text.split())


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
