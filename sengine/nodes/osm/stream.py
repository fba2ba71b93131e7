"""Streaming an OpenStreetMap file into flat arrays, with pyosmium.

The highway ways never reach Python one by one: libosmium's own handlers,
in C++, add the node locations to the ways, keep the highway ways of the
classes asked for (``osmium.filter.TagFilter``) and write them as OPL text
with their locations, which numpy decodes in a few whole-array passes
(:func:`_read_native`; Liège's 80,000 ways in about 0.2 s of CPU, against
0.28 s with a Python callback per way, and 0.37 s when that was shared
between two processes).  The ways come out ordered by OSM id (file order for
the usual sorted extracts) with the class codes numbered by first
appearance.  A file the OPL route does not take (a node outside the valid
range, new objects with negative ids, an unreadable file) is read by the
pyosmium pass with a Python callback per way (:func:`_read_pass`), which
says what is wrong or handles it.

Water, parks and buildings (areas assembled by pyosmium, with a Python
callback per area) are read in a pyosmium pass of their own, side by side
with the ways' when the machine has two cores
(:func:`sengine.parallel.run_jobs`): the extract does not depend on the
number of processes.

Negative ids are those of objects not yet in the OSM database (JOSM's
convention, and that of sengine's own ``streets.osm``): libosmium's node
location index keeps positive ids only, so a file whose ways use negative
nodes is read a second time, its negative nodes' locations kept by a node
callback (:func:`_read_pass` with ``negative``).  Files without them cost
nothing more.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

import numpy as np
import shapely

from sengine.errors import InputDataError
from sengine.parallel import available_cores, can_fork, in_worker, run_jobs

__all__ = ["OsmExtract", "read_osm", "decode_lines", "parse_height", "int_tag", "TAG_KEYS"]

_WATER = {("natural", "water"), ("waterway", "riverbank"), ("landuse", "reservoir"), ("landuse", "basin")}
_PARKS = {("leisure", "park"), ("leisure", "garden")}
#: OSM ``landuse`` (and school ``amenity``) areas -> the buildings' land use (``extras=landuse``).
LANDUSE = {
    ("landuse", "residential"): "residential",
    ("landuse", "commercial"): "commercial",
    ("landuse", "retail"): "commercial",
    ("landuse", "civil"): "office",
    ("landuse", "industrial"): "industrial",
    ("landuse", "education"): "educational",
    ("amenity", "school"): "educational",
    ("amenity", "university"): "educational",
    ("amenity", "college"): "educational",
    ("amenity", "kindergarten"): "educational",
}
#: OSM ``building`` values -> the building's land use (wiki "Key:building", its typology table);
#: ``yes`` and the civic, religious and other types say no use and count as unknown.
BUILDING_USE = {
    **dict.fromkeys(
        (
            "apartments", "residential", "house", "detached", "semidetached_house", "terrace",
            "bungalow", "dormitory", "cabin", "farm", "houseboat", "static_caravan",
        ),
        "residential",
    ),
    **dict.fromkeys(("commercial", "retail", "supermarket", "kiosk", "hotel"), "commercial"),
    **dict.fromkeys(("office", "government"), "office"),
    **dict.fromkeys(("industrial", "warehouse", "manufacture", "factory", "hangar", "depot"), "industrial"),
    **dict.fromkeys(("school", "university", "college", "kindergarten"), "educational"),
}  # fmt: skip
POLYGON_KINDS = ("water", "parks", "buildings", "landuse")
_NUM = re.compile(r"^\s*([0-9]+(?:[.,][0-9]+)?)\s*(m|ft|')?\s*$")
#: The tags kept per way besides ``highway`` (``tunnel`` holds ``covered`` when untagged).
TAG_KEYS = ("name", "layer", "bridge", "tunnel", "oneway")
_UNDEFINED = 2147483647  # libosmium's coordinate of a node missing from the file

#: Files smaller than this (bytes) are read in one process: a fork costs more than it saves.
PARALLEL_BYTES = 1 << 20


def int_tag(value: str | None) -> int:
    """An integer tag (``"2"``, ``"-1"``, ``"1.5"`` -> 1); 0 when absent or unreadable.

    Clamped to +-1,000,000 (an OSM ``layer`` is a small number; ``99999999999999999999``
    would not fit an int64).
    """
    try:
        number = float(value) if value else 0.0
    except ValueError:
        return 0
    if not math.isfinite(number):
        return 0
    return int(max(-1e6, min(1e6, number)))


#: OSM ``roof:shape`` values and the roof kinds of the buildings layer (others: flat).
ROOF_SHAPES = {
    "flat": "flat",
    "skillion": "shed",
    "lean_to": "shed",
    "gabled": "gable",
    "saltbox": "gable",
    "gambrel": "gable",
    "round": "gable",
    "hipped": "hip",
    "half-hipped": "hip",
    "side_hipped": "hip",
    "mansard": "hip",
    "pyramidal": "pyramid",
    "cone": "pyramid",
    "dome": "pyramid",
    "onion": "pyramid",
}


def parse_height(value: str | None) -> float:
    """A height tag in metres (``"12"``, ``"12.5 m"``, ``"40 ft"``); NaN when unreadable."""
    if not value:
        return float("nan")
    m = _NUM.match(value)
    if not m:
        return float("nan")
    h = float(m.group(1).replace(",", "."))
    return h * 0.3048 if m.group(2) in ("ft", "'") else h


@dataclass
class OsmExtract:
    """What :func:`read_osm` collects, still in WGS84.

    Attributes
    ----------
    fixed : ndarray (n, 2) of int64
        Every node of every kept highway way, way after way,
        as (lon, lat) in libosmium's fixed point (1e-7 deg): equal values
        are the same place.
    line : ndarray (n,) of int64
        Index of each point's way (non-decreasing).
    way_id, code : ndarray (w,) of int64
        Per kept way, ascending OSM id: the id and the code of its ``highway`` value in ``codes``.
    codes : dict of str to int
        ``highway`` value -> code, numbered by first appearance.
    tags : dict of str to ndarray (w,) of object
        ``name``, ``layer``, ``bridge``, ``tunnel`` (``tunnel`` or else
        ``covered``) and ``oneway`` values per way, None when absent.
    node_ids : ndarray (n,) of int64 or None
        OSM node id of each point (only when asked for).
    polygons : dict of str to (list of str, list of dict)
        ``"water"``, ``"parks"``, ``"buildings"``, ``"landuse"``: hex WKB multipolygons and their attributes.
    clipped : int
        Ways whose nodes are partly missing from the file (cut by the extract's bounding box).
    coastline : list of str
        Hex WKB LineStrings (lon, lat) of the ``natural=coastline`` ways, read
        with the water: land on their left, the sea on their right.
    """

    fixed: np.ndarray = field(default_factory=lambda: np.empty((0, 2), np.int64))
    line: np.ndarray = field(default_factory=lambda: np.empty(0, np.int64))
    way_id: np.ndarray = field(default_factory=lambda: np.empty(0, np.int64))
    code: np.ndarray = field(default_factory=lambda: np.empty(0, np.int64))
    codes: dict = field(default_factory=dict)
    tags: dict = field(default_factory=dict)
    node_ids: np.ndarray | None = None
    polygons: dict = field(default_factory=lambda: {k: ([], []) for k in POLYGON_KINDS})
    clipped: int = 0
    coastline: list = field(default_factory=list)


@dataclass
class _Ways:
    """The ways one pass collected, in its file order (small and picklable: it crosses a pipe)."""

    fixed: np.ndarray  # (n, 2) int32, libosmium fixed point
    size: np.ndarray  # points per way
    way_id: np.ndarray
    code: np.ndarray  # into names
    names: list
    more: list  # (way index, name, layer, bridge, tunnel, oneway) of ways with more tags than highway
    node_ids: np.ndarray | None
    clipped: int
    polygons: dict  # the areas of the pass (see OsmExtract.polygons), empty without extras
    coastline: list  # hex WKB of the coastline ways (with the water only)
    negative: bool = False  # some way uses a node with a negative id that the location index cannot hold


def read_osm(
    path: str | Path,
    *,
    classes: frozenset[str] | None = None,
    extras: frozenset[str] = frozenset(),
    node_ids: bool = False,
    where: str | None = None,
    workers: int | None = None,
) -> OsmExtract:
    """Stream an OSM file and collect its highway ways (and optional areas).

    Parameters
    ----------
    path : str or Path
        ``.osm``, ``.osm.bz2``, ``.osm.gz`` or ``.osm.pbf``.
    classes : frozenset of str, optional
        ``highway`` values to keep; all when None.
    extras : frozenset of str
        Any of ``"water"``, ``"parks"``, ``"buildings"``: also assemble those
        areas (closed ways and multipolygon relations, with pyosmium; costs
        a pass over the relations).
    node_ids : bool
        Also keep the OSM node id of every way node (slower).
    where : str, optional
        Prefix for error messages.
    workers : int, optional
        Processes reading the file when ``extras`` are asked for: 1, or 2 to
        assemble the areas in one process while libosmium reads the ways in
        the other.  Default: 2 for a file of at least :data:`PARALLEL_BYTES`
        on a machine with two free cores, outside a worker process.  The
        result is the same.

    Returns
    -------
    OsmExtract

    Raises
    ------
    InputDataError
        Missing, truncated, corrupt or non-OSM file; a node outside
        [-180, 180] x [-90, 90].
    """
    path = Path(path)
    if not path.is_file():
        raise InputDataError(f"OSM file {str(path)!r} does not exist", where=where)
    out = OsmExtract()
    if workers is None:
        workers = _free_cores() if path.stat().st_size >= PARALLEL_BYTES else 1
    if not extras:  # the ways alone: libosmium does the per-way work
        parts = [_read_ways(path, classes, node_ids=node_ids, where=where)]
    else:
        # the areas in a pyosmium pass whose only ways are the coastline's, the highway ways by libosmium
        # alone: on two cores side by side
        jobs = [
            partial(_read_pass, path, frozenset(), extras=extras, node_ids=node_ids, where=where),
            partial(_read_ways, path, classes, node_ids=node_ids, where=where),
        ]
        if workers >= 2:
            import osmium  # noqa: F401 (before the fork: a child must not wait on an import lock another thread held)

            parts = run_jobs(jobs, 2)
        else:
            parts = [job() for job in jobs]
    if any(p.negative for p in parts):  # new objects (negative ids): read again, keeping their locations
        parts = [_read_pass(path, classes, extras=extras, node_ids=node_ids, where=where, negative=True)]
    for kind, (geoms, attrs) in parts[0].polygons.items():
        out.polygons[kind] = (geoms, attrs)
    out.coastline = parts[0].coastline
    _merge(out, parts, node_ids=node_ids)
    return out


def _read_ways(path: Path, select: frozenset[str] | None, *, node_ids: bool, where) -> _Ways:
    """The highway ways of ``select`` without areas: :func:`_read_native`, else a pyosmium pass."""
    ways = _read_native(path, select, node_ids=node_ids)
    return ways if ways is not None else _read_pass(path, select, extras=frozenset(), node_ids=node_ids, where=where)


def _ways_filter(osmium, select: frozenset[str] | None, sea: bool):
    """The way filter of libosmium: the highway ways of ``select`` (all when None), and the coastline with ``sea``."""
    if select is not None and not select and not sea:  # no way at all: areas, nodes and relations pass
        return osmium.filter.EntityFilter(osmium.osm.ALL & ~osmium.osm.WAY)
    if select is None:
        ways_filter = osmium.filter.KeyFilter("highway", *(("natural",) if sea else ()))
    else:
        coastline = (("natural", "coastline"),) if sea else ()
        ways_filter = osmium.filter.TagFilter(*(("highway", c) for c in sorted(select)), *coastline)
    ways_filter.enable_for(osmium.osm.WAY)  # areas, nodes and relations pass untouched
    return ways_filter


_OPL_ESCAPE = re.compile(r"%([0-9a-fA-F]+)%")
#: What stands in the OPL text for a node without a location (``n12xy``): far outside any valid one.
_MISSING = 999_999_999


def _read_native(path: Path, select: frozenset[str] | None, *, node_ids: bool) -> _Ways | None:
    """The highway ways of ``select`` read by libosmium alone, with no Python call per way.

    libosmium's own handlers, in C++, add the node locations to the ways
    (``NodeLocationsForWays``), keep the highway ways of the classes
    (``EntityFilter``, ``TagFilter``) and write them as OPL text with their
    locations (``locations_on_ways``) to a temporary file, which numpy
    and one regular expression decode: Liège's 80,000 ways cost 0.07 s in
    libosmium and about as much to decode, against 0.28 s with a Python
    callback per way (:func:`_read_pass`).  The extract is the same as that
    pass's: coordinates are written in libosmium's fixed point (7 decimals)
    and read back exactly, tags are unescaped, clipped ways keep their
    longest run of located nodes.

    Returns None, so that the caller falls back on :func:`_read_pass`, for
    what that pass reports or handles itself: an unreadable file, a node
    outside [-180, 180] x [-90, 90], a way using nodes with negative ids.
    """
    import ctypes
    import tempfile

    import osmium

    with tempfile.TemporaryDirectory(prefix="sengine-osm-") as tmp:
        opl = Path(tmp) / "ways.opl"
        try:
            locations = osmium.NodeLocationsForWays(osmium.index.create_map("flex_mem"))
            locations.ignore_errors()  # a node cut off by the extract: its way is clipped below
            # a thread pool of its own, not libosmium's global one: a forked reader must not inherit its threads
            pool = osmium.io.ThreadPool()
            fmt = "opl,locations_on_ways=true,add_metadata=false"
            writer = osmium.SimpleWriter(osmium.io.File(str(opl), fmt), thread_pool=pool)
        except (RuntimeError, ValueError):
            return None
        try:
            ways_only = osmium.filter.EntityFilter(osmium.osm.WAY)
            with osmium.io.Reader(str(path), osmium.osm.NODE | osmium.osm.WAY, thread_pool=pool) as reader:
                osmium.apply(reader, locations, ways_only, _ways_filter(osmium, select, False), writer)
            writer.close()
        except (RuntimeError, ValueError, osmium.InvalidLocationError):
            # a writer that failed (a node outside the valid range) throws again from its C++ destructor,
            # which aborts the process: it is kept alive instead, and the pyosmium pass says what is wrong
            for kept in (writer, pool):
                ctypes.pythonapi.Py_IncRef(ctypes.py_object(kept))
            return None
        data = opl.read_bytes()
    return _decode_opl(data, node_ids=node_ids)


class _Lossy(Exception):
    """OPL text that does not say which code point it escaped."""


def _code_point(m: re.Match) -> str:
    if len(m.group(1)) > 4:  # libosmium writes U+100000 as %10000% too: ambiguous
        raise _Lossy  # (any escape of five or more digits goes to the pyosmium pass)
    return chr(int(m.group(1), 16))


def _unescape(text: bytes) -> str:
    """An OPL key or value: UTF-8 with ``%hex%`` escapes of the code points OPL reserves."""
    s = text.decode("utf-8")
    return _OPL_ESCAPE.sub(_code_point, s) if "%" in s else s


def _decode_opl(data: bytes, *, node_ids: bool) -> _Ways | None:
    """:func:`_decode_opl_ways`, or None for a tag OPL wrote ambiguously."""
    try:
        return _decode_opl_ways(data, node_ids=node_ids)
    except _Lossy:  # a tag with a code point beyond U+FFFF escaped: read by the pyosmium pass
        return None


def _decode_opl_ways(data: bytes, *, node_ids: bool) -> _Ways | None:
    """The :class:`_Ways` of libosmium's OPL ways (see :func:`_read_native`); None for what it does not handle.

    Each line is ``w<id> T<tags> N<nodes>``, the tags escaped so that they
    hold no space, and a node ``n<ref>x<lon>y<lat>`` (``n<ref>xy`` when its
    location is missing).  The lines' structure is found with numpy on the
    bytes (spaces, commas); the tag texts that hold digits are blanked, every
    byte but the digits, ``-`` and ``.`` turns to a space, and the ids,
    refs and coordinates left are parsed by one ``numpy.fromstring``.  Only
    the distinct tag texts (a few classes) and the ways with more tags than
    ``highway`` go through Python.
    """
    if not data:
        return _Ways(np.empty((0, 2), np.int32), np.empty(0, np.int64), np.empty(0, np.int64),
                     np.empty(0, np.int64), [], [], np.empty(0, np.int64) if node_ids else None, 0, {}, [])  # fmt: skip
    buf = np.frombuffer(data, np.uint8)
    nl = np.flatnonzero(buf == 10)
    sp = np.flatnonzero(buf == 32)
    nlines = len(nl)
    if nl[-1] != len(buf) - 1 or len(sp) != 2 * nlines:
        return None
    sp = sp.reshape(-1, 2)
    start = np.r_[0, nl[:-1] + 1]
    if not (
        np.all(buf[start] == ord("w"))
        and np.all(sp[:, 0] > start + 1)
        and np.all(sp[:, 1] < nl)
        and np.all(buf[sp[:, 0] + 1] == ord("T"))
        and np.all(buf[sp[:, 1] + 1] == ord("N"))
    ):
        return None  # not the layout asked for
    # the lines' structure from their commas: between tags, or between nodes
    commas = np.flatnonzero(buf == ord(","))
    at = np.searchsorted(nl, commas)
    in_tags = commas < sp[at, 1]
    npts = np.bincount(at[~in_tags], minlength=nlines) + (nl - sp[:, 1] > 2)
    ts, te = sp[:, 0] + 2, sp[:, 1]
    several = np.zeros(nlines, bool)
    several[at[in_tags]] = True
    several |= te - ts > _TAG_WIDTH
    # the distinct tag texts of one tag (highway=...), found by numpy
    one = np.flatnonzero(~several)
    distinct, inv = [], np.zeros(0, np.int64)
    if len(one):
        width = int((te[one] - ts[one]).max())
        cols = ts[one, None] + np.arange(width)
        mat = np.where(cols < te[one, None], buf[np.minimum(cols, len(buf) - 1)], 0).astype(np.uint8)
        values, inv = np.unique(mat.view(f"S{width}").ravel(), return_inverse=True)
        distinct, inv = values.tolist(), inv.ravel()
    # the tag texts that could read as numbers are blanked; the others turn to spaces with the letters
    blank = several.copy()
    blank[one] = np.array([_NUMBERS.search(t) is not None for t in distinct], bool)[inv]
    rows = np.flatnonzero(blank)
    text = data
    if len(rows):
        head = te[rows] + 2 - sp[rows, 0]
        arr = buf.copy()
        arr[np.repeat(sp[rows, 0] - (np.cumsum(head) - head), head) + np.arange(int(head.sum()))] = 32
        text = arr.tobytes()
    if b"xy" in text:
        text = text.replace(b"xy", b"x%dy%d" % (_MISSING, _MISSING))
    text = text.translate(_OPL_NUMBERS)
    vals = np.fromstring(text, sep=" ")
    if vals.size != nlines + 3 * int(npts.sum()):
        return None
    at_id = np.zeros(vals.size, bool)
    at_id[np.cumsum(1 + 3 * npts) - (1 + 3 * npts)] = True
    ids, vals = vals[at_id].astype(np.int64), vals[~at_id]
    vals = vals.reshape(-1, 3)
    refs, lonlat = vals[:, 0].astype(np.int64), vals[:, 1:]
    missing = lonlat[:, 0] == _MISSING
    if np.any(np.abs(lonlat[~missing, 0]) > 180.0) or np.any(np.abs(lonlat[~missing, 1]) > 90.0):
        return None  # the pyosmium pass names the node
    if np.any(refs[missing] < 0):
        return None  # new objects (negative ids): the pyosmium pass keeps their locations
    line = np.repeat(np.arange(nlines), npts)
    keep_pt = ~missing
    clip = np.bincount(line[missing], minlength=nlines) > 0
    first = np.cumsum(npts) - npts
    for w in np.flatnonzero(clip).tolist():  # the longest run of located nodes (the first of the longest)
        ok = keep_pt[first[w] : first[w] + npts[w]]
        runs = np.flatnonzero(np.diff(np.r_[0, ok.astype(np.int8), 0])).reshape(-1, 2)
        if len(runs):
            a, b = runs[int(np.argmax(runs[:, 1] - runs[:, 0]))]
            ok[:] = False
            ok[a:b] = True
    size = np.bincount(line[keep_pt], minlength=nlines)
    kept = size >= 2
    keep_pt &= kept[line]
    # the class of each way, the other tags of the kept ways with more than highway
    codes: dict = {}
    code_all = np.empty(nlines, np.int64)
    if len(one):
        hw = [codes.setdefault(_unescape(t.partition(b"=")[2]), len(codes)) for t in distinct]
        code_all[one] = np.asarray(hw, np.int64)[inv]
    kept_idx = np.flatnonzero(kept)
    rank = np.cumsum(kept) - 1
    more = []
    for i in np.flatnonzero(several).tolist():
        tags = dict(tuple(_unescape(x) for x in kv.split(b"=", 1)) for kv in data[ts[i] : te[i]].split(b","))
        code_all[i] = codes.setdefault(tags["highway"], len(codes))
        if kept[i] and len(tags) > 1:
            more.append((int(rank[i]), tags.get("name"), tags.get("layer"), tags.get("bridge"),
                         tags.get("tunnel") or tags.get("covered"), tags.get("oneway")))  # fmt: skip
    code_of = code_all[kept_idx]
    return _Ways(
        np.rint(lonlat[keep_pt] * 1e7).astype(np.int32),
        size[kept],
        ids[kept],
        code_of,
        list(codes),
        more,
        refs[keep_pt] if node_ids else None,
        int(clip.sum()),
        {},
        [],
    )


#: Every byte but the digits, the minus sign and the decimal point turned to a space.
_OPL_NUMBERS = bytes(c if chr(c) in "0123456789-." else 32 for c in range(256))
#: Tag text that would leave numbers behind (``xy`` turns into the missing location's).
_NUMBERS = re.compile(rb"[0-9.-]|xy")
#: Tag texts longer than this (bytes) are read by Python (a highway=* tag alone is shorter).
_TAG_WIDTH = 40


def _free_cores() -> int:
    """2 when a second reader would get a core of its own; 1 in a worker process or without a safe fork."""
    return 1 if in_worker() or not can_fork() else min(2, available_cores())


def _read_pass(
    path: Path, select: frozenset[str] | None, *, extras, node_ids: bool, where, negative: bool = False
) -> _Ways:
    """One pyosmium pass: the highway ways whose class is in ``select`` (all when None), and the ``extras`` areas.

    The class filter runs in libosmium (C++), so that other ways never
    reach Python.  With ``negative``, a node callback keeps the locations
    of the nodes with negative ids, which the ways then use.
    """
    import osmium

    wkb = osmium.geom.WKBFactory()
    create, every = wkb.create_linestring, osmium.geom.ALL
    hex_wkb: list = []
    way_id: list = []
    code_l: list = []
    more: list = []
    refs: list = []
    codes: dict = {}
    append_line, append_id, append_code, append_more = hex_wkb.append, way_id.append, code_l.append, more.append
    clipped = [0]
    neg: dict | None = {} if negative else None
    uses_negative = [False]

    def node(n):
        if n.id < 0 and n.location.valid():
            neg[n.id] = (n.location.lon, n.location.lat, n.id)

    coast: list = []
    sea = "water" in extras

    def way(w):
        tags = w.tags
        hw = tags.get("highway")
        if hw is None:  # the filter lets natural=* ways through only to find the coastline
            if sea and tags.get("natural") == "coastline":
                try:
                    coast.append(create(w, every))
                except (osmium.InvalidLocationError, RuntimeError):
                    pass  # clipped by the extract: its other pieces still close the sea
            return
        code = codes.get(hw)
        if code is None:
            code = codes[hw] = len(codes)
        kept = None
        try:
            append_line(create(w, every))
        except osmium.InvalidLocationError:
            if neg is None and not uses_negative[0] and any(n.ref < 0 for n in w.nodes):
                uses_negative[0] = True
            kept = _clipped_way(w, path, hex_wkb, where, neg)
            if neg is None or len(kept or ()) < len(w.nodes):
                clipped[0] += 1
            if kept is None:
                return
        except RuntimeError:  # libosmium geometry_error: a way of fewer than two nodes
            return
        append_id(w.id)
        append_code(code)
        if len(tags) > 1:  # most Liège-like street tables carry highway only
            append_more(
                (
                    len(code_l) - 1,
                    tags.get("name"),
                    tags.get("layer"),
                    tags.get("bridge"),
                    tags.get("tunnel") or tags.get("covered"),
                    tags.get("oneway"),
                )
            )
        if node_ids:
            refs.append(kept if kept is not None else [n.ref for n in w.nodes])

    callbacks = {"way": way}
    if negative:
        callbacks["node"] = node
    polygons: dict = {}
    if extras:
        polygons = {k: ([], []) for k in POLYGON_KINDS}
        callbacks["area"] = _area_callback(wkb, extras, polygons)
    ways_filter = _ways_filter(osmium, select, sea)
    try:
        osmium.make_simple_handler(**callbacks).apply_file(str(path), locations=True, filters=[ways_filter])
    except InputDataError:
        raise
    except (RuntimeError, ValueError, osmium.InvalidLocationError) as exc:
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InputDataError(f"cannot read OSM file {str(path)!r}: {msg}", where=where) from None
    lonlat, line = decode_lines(hex_wkb)
    return _Ways(
        np.rint(lonlat * 1e7).astype(np.int32),
        np.bincount(line, minlength=len(code_l)),
        np.asarray(way_id, np.int64),
        np.asarray(code_l, np.int64),
        list(codes),
        more,
        np.fromiter((r for way in refs for r in way), np.int64) if node_ids else None,
        clipped[0],
        polygons,
        coast,
        uses_negative[0],
    )


def _area_callback(wkb, extras: frozenset[str], polygons: dict):
    """Pyosmium's area callback filling ``polygons`` (see :attr:`OsmExtract.polygons`)."""
    import osmium

    def area(a):
        tags = a.tags
        kind = None
        if "building" in tags and tags.get("building") != "no":
            kind = "buildings"
        elif any((k, tags.get(k)) in _WATER for k in ("natural", "waterway", "landuse")):
            kind = "water"
        elif ("leisure", tags.get("leisure")) in _PARKS:
            kind = "parks"
        use = LANDUSE.get(("landuse", tags.get("landuse"))) or LANDUSE.get(("amenity", tags.get("amenity")))
        if kind == "buildings":  # the building's own type first (building=apartments), then its landuse / amenity
            use = BUILDING_USE.get(tags.get("building", "").strip().lower()) or use
        if kind is None and use is not None:
            kind = "landuse"
        if kind is None or kind not in extras:
            return
        try:
            geom = wkb.create_multipolygon(a)
        except (osmium.InvalidLocationError, RuntimeError):
            return  # broken or clipped ring: skipped like osmium-tool does
        geoms, attrs = polygons[kind]
        geoms.append(geom)
        attrs.append(
            {
                "osm_id": a.orig_id(),
                "name": tags.get("name", ""),
                "height": parse_height(tags.get("height")),
                "levels": int_tag(tags.get("building:levels")),
                "roof": ROOF_SHAPES.get(tags.get("roof:shape", "flat").strip().lower(), "flat"),
                "roof_height": parse_height(tags.get("roof:height")),
                "use": use or "",
            }
        )

    return area


def _merge(out: OsmExtract, parts: list[_Ways], *, node_ids: bool) -> None:
    """Fill ``out``'s way arrays from the passes: ways by ascending id, codes by first appearance."""
    names = [c for p in parts for c in p.names]
    shift = np.cumsum([0] + [len(p.names) for p in parts])[:-1]
    way_id = np.concatenate([p.way_id for p in parts])
    code = np.concatenate([p.code + s for p, s in zip(parts, shift, strict=True)])
    size = np.concatenate([p.size for p in parts])
    fixed = np.concatenate([p.fixed for p in parts]).astype(np.int64)
    ids = np.concatenate([p.node_ids for p in parts]) if node_ids else None
    base = np.cumsum([0] + [len(p.way_id) for p in parts])[:-1]
    more = [(i + b, *rest) for p, b in zip(parts, base, strict=True) for i, *rest in p.more]
    out.clipped = sum(p.clipped for p in parts)
    order = np.argsort(way_id, kind="stable")
    start = np.cumsum(size) - size
    rank = np.empty(len(order), np.int64)
    rank[order] = np.arange(len(order))
    if np.any(order[1:] < order[:-1]):  # not in id order yet: move each way's points with it
        size = size[order]
        pts = np.repeat(start[order] - (np.cumsum(size) - size), size) + np.arange(int(size.sum()))
        fixed = fixed[pts]
        ids = ids[pts] if ids is not None else None
        way_id, code = way_id[order], code[order]
    # codes by first appearance in id order
    seen, first = np.unique(code, return_index=True)
    renum = np.zeros(len(names), np.int64)
    renum[seen[np.argsort(first)]] = np.arange(len(seen))
    out.codes = {names[c]: i for i, c in enumerate(seen[np.argsort(first)].tolist())}
    out.code = renum[code]
    out.way_id = way_id
    out.fixed = fixed
    out.line = np.repeat(np.arange(len(way_id), dtype=np.int64), size)
    out.node_ids = ids
    out.tags = {k: np.full(len(way_id), None, dtype=object) for k in TAG_KEYS}
    if more:
        i, *cols = zip(*more, strict=True)
        i = rank[np.asarray(i, np.int64)]
        for k, col in zip(TAG_KEYS, cols, strict=True):
            out.tags[k][i] = col


def _clipped_way(w, path, hex_wkb, where, negative: dict | None = None) -> list[int] | None:
    """Slow path for a way with missing node locations: keep its longest run of located nodes.

    ``negative`` holds the ``(lon, lat, id)`` of the nodes with negative ids.
    Returns the OSM ids of the kept nodes, or None when fewer than two are left.
    """
    runs, run = [], []
    for n in w.nodes:
        loc = n.location
        if loc.valid():
            run.append((loc.lon, loc.lat, n.ref))
            continue
        if negative is not None and n.ref in negative:
            run.append(negative[n.ref])
            continue
        if loc.x != _UNDEFINED or loc.y != _UNDEFINED:  # present, but outside the valid range
            raise InputDataError(
                f"OSM file {str(path)!r}: node {n.ref} has coordinates ({loc.x / 1e7}, {loc.y / 1e7}) "
                "outside [-180, 180] x [-90, 90]",
                where=where,
            )
        runs.append(run)
        run = []
    runs.append(run)
    best = max(runs, key=len)
    if len(best) < 2:
        return None
    hex_wkb.append(shapely.to_wkb(shapely.linestrings([p[:2] for p in best]), hex=True))
    return [p[2] for p in best]


def decode_lines(hex_wkb: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Coordinates and line index of a list of hex WKB LineStrings, without a geometry per line.

    libosmium writes little-endian 2D LineStrings (1 byte order, 4 bytes type,
    4 bytes count, 16 bytes per point); the whole list is decoded by numpy
    in one go.

    Returns
    -------
    xy : ndarray (n, 2) of float64
    line : ndarray (n,) of int64
        Index of each point's line, ascending.
    """
    if not hex_wkb:
        return np.empty((0, 2)), np.empty(0, np.int64)
    nbytes = np.fromiter(map(len, hex_wkb), np.int64, len(hex_wkb)) // 2
    raw = np.frombuffer(bytes.fromhex("".join(hex_wkb)), np.uint8)
    header = raw[(np.cumsum(nbytes) - nbytes)[:, None] + np.arange(9)]
    if not (np.all(header[:, 0] == 1) and np.all(header[:, 1:5].copy().view("<u4").ravel() == 2)):
        # not the libosmium layout (e.g. our own fallback WKB): let GEOS decode
        xy, line = shapely.get_coordinates(shapely.from_wkb(hex_wkb), return_index=True)
        return xy, line.astype(np.int64)
    npts = header[:, 5:9].copy().view("<u4").ravel().astype(np.int64)
    first = np.cumsum(nbytes) - nbytes + 9
    line = np.repeat(np.arange(len(hex_wkb), dtype=np.int64), npts)
    k = np.arange(line.size) - np.repeat(np.cumsum(npts) - npts, npts)
    offsets = first[line] + 16 * k
    xy = raw[offsets[:, None] + np.arange(16)].view("<f8").reshape(-1, 2)
    return xy, line
