"""The variants of a batch: seeds, image-map sets, parameter sweeps and a manifest, combined.

``sengine batch`` makes one city per variant.  A variant is a seed, a set of
image maps and parameter values over one configuration; the sources multiply:

* ``--seeds 1-10,20``: seeds, as a list or ranges;
* ``--maps landuse=lu/*.png height=h/*.png``: one variant per file stem,
  the files of each kind paired by stem (``lu/a.png`` with ``h/a.png``);
* ``--set NODE.PARAM=v1,v2,v3``: a sweep, one variant per value (a single
  value sets the parameter for every variant, as in ``sengine run``);
* ``--manifest variants.csv``: one variant per row; columns ``id``,
  ``seed``, ``NODE.PARAM`` (a parameter value) and any other name (an image
  map of that kind, a path relative to the manifest).  An empty cell keeps
  the configuration's value.

Every variant has a stable, readable id that names its folder: the
manifest's ``id`` (or its row's values), the maps' stem, ``s<seed>`` and
``node.param=value`` for each sweep, joined by ``-`` (``north-s7``,
``s3-lots.depth=18``); with nothing varied it is ``s<seed>`` of the
configuration.  Everything here is checked before anything runs, and a
mistake is one line naming the option or the manifest's file and line.
"""

from __future__ import annotations

import csv
import glob
import itertools
import math
import re
from dataclasses import dataclass
from pathlib import Path

from .errors import ConfigError, InputDataError

__all__ = ["Variant", "MAX_VARIANTS", "parse_seeds", "pair_maps", "parse_sweeps", "read_manifest", "plan_variants"]

MAX_VARIANTS = 100_000  # a batch of more cities is surely a typo (--seeds 1-1000000000)
MAX_SEED = 2**63 - 1
RESERVED = frozenset({"batch.csv", "batch.parquet", "contact.png"})  # the batch's own files beside the variants
_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._=+-]*$")
_TARGET = re.compile(r"^[^.\s]+\.[^.\s=]+$")


@dataclass(frozen=True)
class Variant:
    """One city of a batch.

    Attributes
    ----------
    id : str
        Folder name and row id: letters, digits and ``. _ = + -``.
    seed : int or None
        Network seed; None keeps the configuration's.
    maps : tuple of (kind, path, where)
        Image maps replacing the configuration's (absolute paths).
    params : tuple of (``NODE.PARAM``, value, where)
        Parameter values, as text (checked by the node's declaration).
    where : str
        The option or manifest line the variant comes from.
    """

    id: str
    seed: int | None = None
    maps: tuple[tuple[str, str, str], ...] = ()
    params: tuple[tuple[str, str, str], ...] = ()
    where: str = ""

    def inputs(self) -> dict:
        """What the variant varies: ``{"seed", "maps": {kind: path}, "params": {NODE.PARAM: value}}``."""
        return {
            "seed": self.seed,
            "maps": {k: p for k, p, _ in self.maps},
            "params": {t: v for t, v, _ in self.params},
        }


def parse_seeds(text: str, *, where: str = "--seeds") -> list[int]:
    """Seeds from ``"1-10,20"``: whole numbers and increasing ranges, each seed once.

    Raises
    ------
    ConfigError
        A part that is not a number or range, a range running backwards, a
        seed given twice or more than :data:`MAX_VARIANTS` seeds.
    """
    parts = [p.strip() for p in text.split(",")]
    ranges: list[tuple[int, int]] = []
    total = 0
    for part in parts:
        m = re.fullmatch(r"(\d+)(?:\s*-\s*(\d+))?", part)
        if not m:
            raise ConfigError(
                f"{text!r}: {part!r} is not a seed (a whole number >= 0) or a range like 1-10", where=where
            )
        a = int(m.group(1))
        b = int(m.group(2)) if m.group(2) is not None else a
        if b < a:
            raise ConfigError(f"{text!r}: the range {part} runs backwards (write {b}-{a})", where=where)
        if b > MAX_SEED:
            raise ConfigError(f"{text!r}: seed {b} is above the largest seed, 2**63 - 1", where=where)
        total += b - a + 1
        if total > MAX_VARIANTS:
            n = sum(y - x + 1 for x, y in ranges) + (b - a + 1)
            raise ConfigError(
                f"{text!r} gives {n:,} seeds or more; a batch makes at most {MAX_VARIANTS:,} cities", where=where
            )
        ranges.append((a, b))
    seeds = [s for a, b in ranges for s in range(a, b + 1)]
    if len(set(seeds)) != len(seeds):
        seen: set[int] = set()
        twice = next(s for s in seeds if s in seen or seen.add(s))
        raise ConfigError(f"{text!r}: seed {twice} is given twice", where=where)
    return seeds


def pair_maps(specs: list[str], *, base_dir: Path | None = None) -> list[tuple[str, tuple[tuple[str, str, str], ...]]]:
    """Image-map sets from ``KIND=GLOB`` specs, paired by file stem.

    Parameters
    ----------
    specs : list of str
        ``landuse=maps/lu/*.png``; a folder stands for its ``*.png`` files.
    base_dir : path, optional
        Folder relative patterns start from (default: the current one).

    Returns
    -------
    list of (stem, maps)
        One entry per stem, sorted by stem; ``maps`` as in :attr:`Variant.maps`.

    Raises
    ------
    ConfigError
        A spec not ``KIND=GLOB``, a kind given twice, a pattern matching no
        file, two files of one kind with one stem, or a stem found in one
        kind's files but not in another's (naming it).
    """
    base = Path(base_dir) if base_dir is not None else Path.cwd()
    by_kind: dict[str, dict[str, Path]] = {}
    pattern_of: dict[str, str] = {}
    for spec in specs:
        kind, sep, pattern = spec.partition("=")
        kind, pattern = kind.strip(), pattern.strip()
        where = f"--maps {spec}"
        if not sep or not re.fullmatch(r"[A-Za-z_][\w-]*", kind) or not pattern:
            raise ConfigError("must be KIND=PATTERN, e.g. landuse=maps/lu/*.png", where=where)
        if kind in by_kind:
            raise ConfigError(f"the map kind {kind!r} is given twice (also {pattern_of[kind]})", where=where)
        full = Path(pattern) if Path(pattern).is_absolute() else base / pattern
        if full.is_dir():
            full = full / "*.png"
        files = sorted(Path(p).resolve() for p in glob.glob(str(full)) if Path(p).is_file())
        if not files:
            raise ConfigError(f"{pattern!r} matches no file", where=where)
        stems: dict[str, Path] = {}
        for f in files:
            if f.stem in stems:
                raise ConfigError(f"two {kind} maps have the stem {f.stem!r}: {stems[f.stem]} and {f}", where=where)
            stems[f.stem] = f
        by_kind[kind] = stems
        pattern_of[kind] = pattern
    if not by_kind:
        return []
    kinds = list(by_kind)
    everything = sorted(set().union(*(set(s) for s in by_kind.values())))
    for stem in everything:
        has = [k for k in kinds if stem in by_kind[k]]
        lacks = [k for k in kinds if stem not in by_kind[k]]
        if lacks:
            raise ConfigError(
                f"the stem {stem!r} has a {has[0]} map ({by_kind[has[0]][stem]}) but no {lacks[0]} map "
                f"in {pattern_of[lacks[0]]!r}: every kind needs a file of each stem",
                where="--maps",
            )
    return [
        (stem, tuple((k, str(by_kind[k][stem]), f"--maps {k}={pattern_of[k]}") for k in kinds)) for stem in everything
    ]


def parse_sweeps(sets: list[str]) -> tuple[list[str], list[tuple[str, list[str]]]]:
    """Split ``--set`` options into fixed ones and sweeps.

    ``NODE.PARAM=VALUE`` sets a value for every variant;
    ``NODE.PARAM=v1,v2,v3`` sweeps the values (one variant each).  A value
    holding commas is written with spaces instead (``"800 260"``) or given
    in a manifest.

    Returns
    -------
    fixed : list of str
        ``NODE.PARAM=VALUE`` items for :func:`sengine.xmlconfig.load_config`.
    sweeps : list of (target, values)
        In option order.
    """
    fixed: list[str] = []
    sweeps: list[tuple[str, list[str]]] = []
    seen: set[str] = set()
    for item in sets:
        target, sep, value = item.partition("=")
        target = target.strip()
        where = f"--set {target}"
        if not sep or not _TARGET.fullmatch(target):
            raise ConfigError(f"--set {item!r} must be NODE.PARAM=VALUE or NODE.PARAM=v1,v2,v3")
        if target in seen:
            raise ConfigError("the parameter is set twice", where=where)
        seen.add(target)
        values = [v.strip() for v in value.split(",")]
        if len(values) == 1:
            fixed.append(f"{target}={value}")
            continue
        if any(not v for v in values):
            raise ConfigError(f"{value!r} has an empty value in its list", where=where)
        if len(set(values)) != len(values):
            twice = next(v for i, v in enumerate(values) if v in values[:i])
            raise ConfigError(f"{value!r} gives the value {twice!r} twice", where=where)
        sweeps.append((target, values))
    return fixed, sweeps


@dataclass(frozen=True)
class _Row:
    id: str | None
    seed: int | None
    maps: tuple[tuple[str, str, str], ...]
    params: tuple[tuple[str, str, str], ...]
    where: str


def read_manifest(path: Path) -> list[_Row]:
    """The rows of a manifest (CSV with a header): ``id``, ``seed``, ``NODE.PARAM`` and map-kind columns.

    Blank rows and rows whose first cell starts with ``#`` are skipped.  Map
    paths are relative to the manifest's folder and must name existing files.

    Raises
    ------
    ConfigError, InputDataError
        Naming the manifest's file and line: a missing or duplicate column,
        a row of the wrong length, a bad id or seed, a map file not found, a
        duplicate id, or no row at all.
    """
    path = Path(path)
    label = str(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise InputDataError("manifest file not found", where=label) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputDataError(f"cannot read the manifest: {exc}", where=label) from None
    reader = csv.reader(text.splitlines())
    header: list[str] | None = None
    rows: list[_Row] = []
    ids: dict[str, str] = {}
    for cells in reader:
        line = reader.line_num
        where = f"{label}:{line}"
        cells = [c.strip() for c in cells]
        if not any(cells) or cells[0].startswith("#"):
            continue
        if header is None:
            header = cells
            for i, name in enumerate(header):
                if not name:
                    raise ConfigError(f"column {i + 1} of the header has no name", where=where)
                if name in header[:i]:
                    raise ConfigError(f"the column {name!r} is given twice", where=where)
                if "." in name and not _TARGET.fullmatch(name):
                    raise ConfigError(f"the column {name!r} is not NODE.PARAM", where=where)
                if "." not in name and name not in ("id", "seed") and not re.fullmatch(r"[A-Za-z_][\w-]*", name):
                    raise ConfigError(
                        f"the column {name!r} is not id, seed, NODE.PARAM or a map kind (a word)", where=where
                    )
            continue
        if len(cells) != len(header):
            raise ConfigError(f"the row has {len(cells)} cells, the header {len(header)}", where=where)
        vid: str | None = None
        seed: int | None = None
        maps: list[tuple[str, str, str]] = []
        params: list[tuple[str, str, str]] = []
        for name, cell in zip(header, cells):
            if not cell:
                continue
            if name == "id":
                if not _ID.fullmatch(cell):
                    raise ConfigError(
                        f"id {cell!r} may hold only letters, digits and . _ = + - (starting with a letter or digit)",
                        where=where,
                    )
                vid = cell
            elif name == "seed":
                if not re.fullmatch(r"\d+", cell) or int(cell) > MAX_SEED:
                    raise ConfigError(f"seed {cell!r} is not a whole number from 0 to 2**63 - 1", where=where)
                seed = int(cell)
            elif "." in name:
                params.append((name, cell, f"{where}: column {name}"))
            else:
                file = Path(cell) if Path(cell).is_absolute() else path.parent / cell
                if not file.is_file():
                    raise InputDataError(f"column {name}: map file {cell!r} not found", where=where)
                maps.append((name, str(file.resolve()), f"{where}: column {name}"))
        row = _Row(vid, seed, tuple(maps), tuple(params), where)
        key = _row_id(row).lower()
        if key in ids:
            raise ConfigError(f"the variant id {_row_id(row)!r} is also the id of {ids[key]}", where=where)
        ids[key] = where
        rows.append(row)
    if header is None:
        raise ConfigError("the manifest is empty (it needs a header row: id,seed,landuse,...)", where=label)
    if not rows:
        raise ConfigError("the manifest has a header but no variant row", where=label)
    return rows


def _slug(text: str) -> str:
    """``text`` as an id part: runs of other characters become ``_``."""
    return re.sub(r"[^A-Za-z0-9._=+-]+", "_", text).strip("_.") or "_"


def _row_id(row: _Row) -> str:
    if row.id is not None:
        return row.id
    parts = [_slug(Path(p).stem) for _, p, _ in row.maps]
    if row.seed is not None:
        parts.append(f"s{row.seed}")
    parts += [_slug(f"{t}={v}") for t, v, _ in row.params]
    return "-".join(parts) or f"r{row.where.rsplit(':', 1)[-1]}"


def plan_variants(
    *,
    config_seed: int,
    seeds: list[int] | None = None,
    map_sets: list[tuple[str, tuple[tuple[str, str, str], ...]]] | None = None,
    sweeps: list[tuple[str, list[str]]] | None = None,
    manifest: list[_Row] | None = None,
    fixed_maps: tuple[str, ...] = (),
    fixed_sets: tuple[str, ...] = (),
) -> list[Variant]:
    """Every variant: manifest rows x map sets x seeds x sweep values, in that nesting order.

    Parameters
    ----------
    config_seed : int
        The configuration's seed (the id of a batch that varies nothing).
    seeds, map_sets, sweeps, manifest
        From :func:`parse_seeds`, :func:`pair_maps`, :func:`parse_sweeps`
        and :func:`read_manifest`; None or empty varies nothing.
    fixed_maps, fixed_sets
        ``KIND=PATH`` and ``NODE.PARAM=VALUE`` applied to every variant
        (``--map``, single-valued ``--set``): a variant source may not vary
        them too.

    Raises
    ------
    ConfigError
        One thing varied by two sources (seeds by ``--seeds`` and the
        manifest, a map kind, a parameter), more than :data:`MAX_VARIANTS`
        variants, or two variants with one id.
    """
    rows = manifest or [_Row(None, None, (), (), "")]
    sets = map_sets or [("", ())]
    seed_list: list[int | None] = list(seeds) if seeds else [None]
    sweeps = sweeps or []
    n = len(rows) * len(sets) * len(seed_list) * math.prod(len(v) for _, v in sweeps)
    if n > MAX_VARIANTS:
        raise ConfigError(f"the batch would make {n:,} cities; it makes at most {MAX_VARIANTS:,}")
    fixed_kinds = {m.partition("=")[0]: "--map" for m in fixed_maps}
    fixed_targets = {s.partition("=")[0].strip(): "--set" for s in fixed_sets}
    map_kinds = {k for _, maps in sets for k, _, _ in maps}
    sweep_targets = {t for t, _ in sweeps}
    for row in manifest or []:
        if seeds and row.seed is not None:
            raise ConfigError("the seed is given by the manifest's seed column and by --seeds", where=row.where)
        for kind, _, where in row.maps:
            if kind in map_kinds or kind in fixed_kinds:
                other = "--maps" if kind in map_kinds else "--map"
                raise ConfigError(f"the {kind} map is given by the manifest and by {other}", where=where)
        for target, _, where in row.params:
            if target in sweep_targets or target in fixed_targets:
                raise ConfigError(f"{target} is given by the manifest and by --set", where=where)
    both = sorted(map_kinds & set(fixed_kinds))
    if both:
        raise ConfigError(f"the {both[0]} map is given by --maps and by --map", where="--maps")
    variants: list[Variant] = []
    ids: dict[str, str] = {}
    for row, (stem, maps), seed, combo in itertools.product(
        rows, sets, seed_list, itertools.product(*([(t, v) for v in vals] for t, vals in sweeps))
    ):
        parts = []
        if manifest:
            parts.append(_row_id(row))
        if stem:
            parts.append(_slug(stem))
        if seed is not None:
            parts.append(f"s{seed}")
        parts += [_slug(f"{t}={v}") for t, v in combo]
        vid = "-".join(parts) or f"s{config_seed}"
        where = row.where or ", ".join(
            w
            for w in (
                f"--maps stem {stem}" if stem else "",
                f"--seeds {seed}" if seed is not None else "",
                *(f"--set {t}={v}" for t, v in combo),
            )
            if w
        )
        key = vid.lower()
        if key in RESERVED:
            raise ConfigError(f"the variant id {vid!r} is the name of a file the batch writes", where=where or None)
        if key in ids:
            raise ConfigError(f"two variants have the id {vid!r} (also {ids[key]}): give the manifest an id column")
        ids[key] = where or "the configuration"
        variants.append(
            Variant(
                id=vid,
                seed=row.seed if row.seed is not None else seed,
                maps=row.maps + maps,
                params=row.params + tuple((t, v, f"--set {t}") for t, v in combo),
                where=where,
            )
        )
    return variants
