"""The ``sengine`` command: run | batch | validate | nodes | graph | osm | view.

A user mistake prints one line (``sengine: error: WHERE: WHAT``) and exits
with status 2; ``--debug`` shows the traceback instead.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import tempfile
import threading
from collections.abc import Sequence
from functools import partial
from pathlib import Path

from . import __version__, registry
from .errors import SEngineError
from .parallel import available_cores, run_jobs
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


def build_parser() -> argparse.ArgumentParser:
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
    _common(p)

    p = sub.add_parser("batch", help="run a config once per seed into OUT/seed-N")
    p.add_argument("config", type=Path)
    _run_options(p)
    p.add_argument(
        "--seeds", default="1-4", help="seeds as a list or range, e.g. 1,2,5 or 1-10 (--workers N runs N seeds at once)"
    )
    p.add_argument("--map", dest="maps", action="append", default=[], metavar="KIND=PATH")
    _common(p)

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
    return frozenset(f.strip().lower() for f in text.split(",") if f.strip())


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


def _seeds(text: str) -> list[int]:
    seeds: list[int] = []
    for part in text.split(","):
        a, dash, b = part.strip().partition("-")
        try:
            seeds += list(range(int(a), int(b) + 1)) if dash else [int(a)]
        except ValueError:
            raise SEngineError(f"--seeds {text!r} must be numbers or ranges like 1-10") from None
    return seeds


def cmd_run(args: argparse.Namespace) -> int:
    from .xmlconfig import load_config

    net = load_config(args.config, sets=args.sets, maps=args.maps, plugins=args.plugin, seed=args.seed)
    result = net.run(
        out=args.out,
        formats=_formats(args.formats),
        progress=_progress(args),
        workers=args.workers,
        options=_options(args),
    )
    if not args.quiet:
        counts = ", ".join(f"{k} {v:,}" for k, v in result.stats["counts"].items())
        print(f"{args.out}: {counts} in {result.stats['seconds']['total']:.2f} s")
    return 0


def cmd_batch(args: argparse.Namespace) -> int:
    """One run per seed; with ``--workers N`` the seeds run side by side in N processes."""
    from .xmlconfig import load_config

    net = load_config(args.config, sets=args.sets, maps=args.maps, plugins=args.plugin)
    net.validate()
    seeds = _seeds(args.seeds)
    formats = registry.check_formats(_formats(args.formats))
    options = _options(args)
    if args.workers > 1 and len(seeds) > 1:  # seeds side by side, each run in one process
        jobs = [partial(_batch_run, net, seed, args.out, formats, options=options) for seed in seeds]
        stats = run_jobs(jobs, args.workers)
    else:
        stats = [
            _batch_run(net, seed, args.out, formats, _progress(args), args.workers, options=options) for seed in seeds
        ]
    rows = [
        {"seed": seed, "counts": st["counts"], "areas": st["areas"], "report": st["report"]}
        for seed, st in zip(seeds, stats)
    ]
    if not args.quiet:
        for row in rows:
            print(f"seed {row['seed']}: " + ", ".join(f"{k} {v:,}" for k, v in row["counts"].items()))
    (args.out / "batch.json").write_text(json.dumps({"config": str(args.config), "runs": rows}, indent=2) + "\n")
    return 0


def _batch_run(
    net, seed: int, out: Path, formats: frozenset[str], progress=None, workers: int = 1, options=None
) -> dict:
    return net.run(
        seed=seed, out=out / f"seed-{seed}", formats=formats, progress=progress, workers=workers, options=options
    ).stats


def cmd_osm(args: argparse.Namespace) -> int:
    """Run ``networks/loadmap.xml`` on one OSM file with default parameters."""
    from .xmlconfig import load_config

    if not args.file.exists():
        raise SEngineError(f"{args.file}: file not found")
    with tempfile.TemporaryDirectory() as tmp:
        config = Path(tmp) / "osm.xml"
        config.write_text(
            f'<sengine version="1">\n  <city name="{_xml_attr(args.file.name)}"/>\n'
            '  <network base="loadmap"/>\n</sengine>\n'
        )
        net = load_config(config, sets=args.sets, plugins=args.plugin, seed=args.seed)
        # errors about the file name the command, not the temporary config
        net.plan.maps["osm"] = MapSpec("osm", args.file.resolve(), {}, where="sengine osm")
        net.source = str(args.file)
        result = net.run(
            out=args.out,
            formats=_formats(args.formats),
            progress=_progress(args),
            workers=args.workers,
            options=_options(args),
        )
    if not args.quiet:
        counts = ", ".join(f"{k} {v:,}" for k, v in result.stats["counts"].items())
        print(f"{args.out}: {counts} in {result.stats['seconds']['total']:.2f} s")
    return 0


def _xml_attr(text: str) -> str:
    return text.replace("&", "&amp;").replace('"', "&quot;").replace("<", "&lt;")


def cmd_validate(args: argparse.Namespace) -> int:
    from .xmlconfig import load_config

    net = load_config(args.config, sets=args.sets, maps=args.maps, plugins=args.plugin)
    bound = net.validate()
    print(f"{args.config}: valid, {len(bound.nodes)} nodes, {len(bound.edges)} connections")
    return 0


def cmd_nodes(args: argparse.Namespace) -> int:
    from . import registry

    for spec in args.plugin:
        registry.load_plugin(spec, base_dir=Path.cwd(), where=f"--plugin {spec}")
    described = [registry.get(name).describe() for name in registry.names()]
    if args.json:
        print(json.dumps(described, indent=2))
    else:
        for d in described:
            ins = ", ".join(f"{p['name']}:{p['kind']}{'' if p['required'] else '?'}" for p in d["inputs"])
            outs = ", ".join(f"{p['name']}:{p['kind']}" for p in d["outputs"])
            print(f"{d['name']}  ({ins}) -> ({outs})")
            if d["doc"]:
                print(f"    {d['doc']}")
            for p in d["params"]:
                bounds = ""
                if p["min"] is not None or p["max"] is not None:
                    bounds = f" [{'' if p['min'] is None else p['min']}, {'' if p['max'] is None else p['max']}]"
                if p["choices"]:
                    bounds = f" {{{', '.join(p['choices'])}}}"
                unit = f" {p['unit']}" if p["unit"] else ""
                print(f"    - {p['name']}: {p['type']} = {p['default']!r}{unit}{bounds}  {p['doc']}")
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
    from .graphview import write_graph
    from .xmlconfig import load_config

    net = load_config(args.config, plugins=args.plugin)
    write_graph(net, args.out)
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
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as done:  # --help, --version, or a usage error already printed
        return int(done.code or 0)
    logging.basicConfig(
        level=logging.DEBUG if args.debug else logging.WARNING, format="sengine: %(levelname)s: %(message)s"
    )
    try:
        return COMMANDS[args.command](args)
    except SEngineError as err:
        if args.debug:
            raise
        print(f"sengine: error: {_one_line(str(err))}", file=sys.stderr)
        return EXIT_USER_ERROR
    except KeyboardInterrupt:
        print("sengine: interrupted", file=sys.stderr)
        return 130


def _one_line(text: str) -> str:
    return " ".join(text.split())


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
