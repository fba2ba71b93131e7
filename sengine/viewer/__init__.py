"""The city viewer page: ``index.html`` + ``viewer.js`` + ``city.view.js`` in an output folder.

The page shows a city in 3D in a browser (three.js: pan, zoom, orbit; layers
on and off; features coloured by height, use or FAR; a click shows a
feature's attributes) with the plan (``preview.png``) below.  It needs no
network and opens from ``file://``: the city comes in ``city.view.js``, a
script that sets ``window.SENGINE_VIEW``, and the viewer is one JavaScript
file bundled at build time from ``viewer/`` (three.js and esbuild, see
``viewer/package.json``) and shipped here in ``assets/``.

This module knows the page's files and the view format, not what a city is
made of: the exporter (:mod:`sengine.nodes.export.html`, ``--format html``)
turns layers into :class:`ViewLayer` meshes; ``sengine view OUT`` (re)writes
the page around an existing ``city.view.js`` and serves the folder.

The view format (version 1) is a JSON object whose ``bin`` member is the
base64 of every array, in strings of at most :data:`BIN_CHUNK` bytes (one
string of hundreds of MB takes a browser some 25 times longer to parse than
the same text cut in pieces: 80 s against 3 s for whole Liège's 373 MB),
each array at an 8-byte aligned offset named in the
object: per layer float32 positions (x east, y up, z south, metres around the
city's origin, as in the glb), uint32 triangle indices in tiles
(:func:`tiles`) and a float32 row per vertex (exact up to 16.7 million
features), a typical feature's size (``scale``, m), and its columns: ``float``
(float64, NaN for null), ``int`` (int32), ``bool`` (uint8, 2 for null) or
``text`` (codes of 1, 2 or 4 bytes into a list of values).
"""

from __future__ import annotations

import base64
import functools
import json
import logging
import shutil
import threading
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..errors import ParameterError

if TYPE_CHECKING:
    import http.server

__all__ = ["ASSETS", "DATA_FILE", "PAGE_FILES", "ViewLayer", "tiles", "view_text", "write_view", "write_page", "serve"]

log = logging.getLogger(__name__)

#: The page's files shipped with sengine.
ASSETS = Path(__file__).parent / "assets"
#: The page and the viewer, copied into an output folder.
PAGE_FILES = ("index.html", "viewer.js")
#: The city's data, written by the exporter.
DATA_FILE = "city.view.js"
_INT32 = (-(2**31), 2**31 - 1)


@dataclass
class ViewLayer:
    """One layer of the page: a triangle mesh whose every vertex knows its feature, and the features' columns.

    Attributes
    ----------
    name : str
        Layer name (``buildings``, ``lots`` ...).
    colour : tuple of int
        sRGB base colour, 0-255.
    kind : {"solid", "surface", "line"}
        Extruded solids, flat surfaces, or ribbons along lines.
    position : numpy.ndarray, shape (v, 3)
        Vertices, x east, y up, z south (m, around the city's origin).
    index : numpy.ndarray, shape (t, 3)
        Triangles, counter-clockwise seen from outside or above.
    feature : numpy.ndarray, shape (v,)
        Row of each vertex's feature in ``columns``.
    columns : dict of str to numpy.ndarray
        Attribute columns, one value per feature (``id`` first by custom).
    features : int
        Number of features (rows of the columns).
    scale : float, optional
        A typical feature's size (m) that decides when the page leaves its
        detail out (:func:`tiles`); None: the median height of a solid's
        features, the square root of a surface's median feature area.
    """

    name: str
    colour: tuple[int, int, int]
    kind: str
    position: np.ndarray
    index: np.ndarray
    feature: np.ndarray
    columns: dict[str, np.ndarray] = field(default_factory=dict)
    features: int = 0
    scale: float | None = None


class _Blob:
    """Arrays laid end to end at 8-byte aligned offsets."""

    def __init__(self) -> None:
        self.parts: list[bytes] = []
        self.size = 0

    def add(self, array: np.ndarray) -> int:
        data = np.ascontiguousarray(array).tobytes()
        offset = self.size
        pad = -len(data) % 8
        self.parts.append(data + b"\0" * pad)
        self.size += len(data) + pad
        return offset

    def base64(self, chunk: int | None = None) -> list[str]:
        """The arrays as base64 texts of ``chunk`` bytes each (3 bytes to 4 characters), the last shorter."""
        data = b"".join(self.parts)
        step = len(data) if chunk is None else max(3, int(chunk) // 3 * 3)
        return [base64.b64encode(data[k : k + step]).decode("ascii") for k in range(0, len(data), step or 1)]


#: Bytes of the arrays in each base64 string of ``city.view.js`` (12 MB: 16 MB of text).
BIN_CHUNK = 12 * 1024 * 1024
#: Triangles per tile the page aims at: tiles out of view are not drawn, far ones lose their detail.
TILE_TRIANGLES = 5_000
#: Feature sizes (m) whose upward triangles each tile counts (:func:`tiles`).
SIZES = (8.0, 16.0, 32.0, 64.0)


def tiles(position: np.ndarray, index: np.ndarray, feature: np.ndarray, *, per_tile: int = TILE_TRIANGLES):
    """Order triangles by tile for the page: ``(index, tiles)``.

    Features go to the cell of a square grid (about ``per_tile`` triangles a
    cell, at most 64 x 64 cells over the 1st to 99th percentiles of the
    features' centres) that holds the centre of their vertices; a tile's triangles are
    its features', the upward-facing ones (roofs, caps, surfaces) first,
    the largest features' first, and the walls after, so that the page draws
    a far tile's roofs alone, or the roofs of its features that would cover a
    pixel, with one shorter draw range.  ``tiles`` rows are ``[first
    triangle, upward triangles, triangles, xmin, ymin, zmin, xmax, ymax, zmax,
    upward triangles of the features at least 8, 16, 32 and 64 m across]``
    (a feature's size: the square root of its area seen from above).
    """
    t = len(index)
    if t == 0:
        return index, []
    pos = np.asarray(position, np.float32)
    feat = np.asarray(feature, np.int64)
    n = int(feat.max()) + 1
    present = np.bincount(feat, minlength=n) > 0
    counts = np.maximum(np.bincount(feat, minlength=n), 1)
    cx = np.bincount(feat, pos[:, 0], minlength=n) / counts
    cz = np.bincount(feat, pos[:, 2], minlength=n) / counts
    k = int(np.clip(np.ceil(np.sqrt(t / per_tile)), 1, 64))
    # the grid spans the features' centres without their outliers (a road running out of town would stretch every
    # cell); outliers go to the edge cells
    x0, x1 = (float(v) for v in np.percentile(cx[present], [1, 99]))
    z0, z1 = (float(v) for v in np.percentile(cz[present], [1, 99]))
    gx = np.clip(((cx - x0) / max(x1 - x0, 1e-9) * k).astype(np.int64), 0, k - 1)
    gz = np.clip(((cz - z0) / max(z1 - z0, 1e-9) * k).astype(np.int64), 0, k - 1)
    feature_tile = gz * k + gx
    # a wall: a triangle whose normal is less than 60 degrees from horizontal
    a = pos[index[:, 0]]
    u = pos[index[:, 1]] - a
    v = pos[index[:, 2]] - a
    ny = u[:, 2] * v[:, 0] - u[:, 0] * v[:, 2]
    nx = u[:, 1] * v[:, 2] - u[:, 2] * v[:, 1]
    nz = u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]
    wall = ny * ny < 0.25 * (nx * nx + ny * ny + nz * nz)
    # a feature's size: the square root of its upward faces' area seen from above (m)
    tri_feat = feat[index[:, 0]]
    size = np.sqrt(np.bincount(tri_feat, np.where(wall, 0.0, 0.5 * np.abs(ny.astype(np.float64))), minlength=n))
    tri_size = size[tri_feat]
    order = np.lexsort((-tri_size, wall, feature_tile[tri_feat]))
    index, wall, tri_size = index[order], wall[order], tri_size[order]
    tri_tile = feature_tile[feat[index[:, 0]]]
    starts = np.flatnonzero(np.r_[True, tri_tile[1:] != tri_tile[:-1]])
    ends = np.r_[starts[1:], t]
    up = np.add.reduceat(~wall, starts)
    # upward triangles of the features at least 8, 16, 32, 64 m across: a prefix of each tile's upward ones
    big = [np.add.reduceat(~wall & (tri_size >= s_), starts) for s_ in SIZES]
    # bounds of each tile: of its features' vertices
    vtile = feature_tile[feat]
    vorder = np.argsort(vtile, kind="stable")
    vt = vtile[vorder]
    vstarts = np.flatnonzero(np.r_[True, vt[1:] != vt[:-1]])
    p = pos[vorder]
    lo = np.minimum.reduceat(p, vstarts, axis=0)
    hi = np.maximum.reduceat(p, vstarts, axis=0)
    where = {int(tile): j for j, tile in enumerate(vt[vstarts])}
    rows = []
    big = np.column_stack(big).tolist()
    for s, e, u_, tile, b in zip(starts.tolist(), ends.tolist(), up.tolist(), tri_tile[starts].tolist(), big):
        j = where[tile]
        rows.append([s, u_, e - s, *(round(float(x), 2) for x in (*lo[j], *hi[j])), *b])
    return index, rows


def _scale(lay: ViewLayer, pos: np.ndarray, idx: np.ndarray, feat: np.ndarray) -> float:
    """A typical feature's size (m): see :class:`ViewLayer`."""
    if lay.scale is not None:
        return float(lay.scale)
    if len(idx) == 0:
        return 0.0
    rows = feat.astype(np.int64)
    if lay.kind == "solid":
        n = int(rows.max()) + 1
        top = np.full(n, -np.inf)
        bottom = np.full(n, np.inf)
        np.maximum.at(top, rows, pos[:, 1])
        np.minimum.at(bottom, rows, pos[:, 1])
        ok = np.isfinite(top)
        return float(np.median(top[ok] - bottom[ok]))
    p = pos.astype(np.float64)
    a, b, c = p[idx[:, 0]], p[idx[:, 1]], p[idx[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    per = np.bincount(rows[idx[:, 0]], area)
    return float(np.sqrt(np.median(per[per > 0]))) if (per > 0).any() else 0.0


def _home(layers: Sequence[ViewLayer]) -> list[float] | None:
    """The bounds the page first shows: the city without its outliers.

    The 0.5 and 99.5 percentiles of the vertices: a road that runs out of town is left out.
    """
    pos = [np.asarray(lay.position, np.float32).reshape(-1, 3) for lay in layers if len(lay.position)]
    if not pos:
        return None
    p = np.concatenate(pos)
    if len(p) > 1_000_000:  # a regular sample is as good for percentiles
        p = p[:: len(p) // 1_000_000]
    lo = np.percentile(p, 0.5, axis=0)
    hi = np.percentile(p, 99.5, axis=0)
    lo[1], hi[1] = min(float(p[:, 1].min()), 0.0), float(p[:, 1].max())
    return [round(float(v), 2) for v in (*lo, *hi)]


def _column(blob: _Blob, name: str, values: np.ndarray) -> dict:
    """A column of the view format (see the module notes)."""
    col = np.asarray(values)
    if col.dtype.kind == "O":  # numbers or booleans with nulls, or text
        items = col.tolist()
        present = [v for v in items if v is not None and not (isinstance(v, float) and np.isnan(v))]
        if present and all(isinstance(v, bool) for v in present):
            codes = np.array([2 if v is None else int(bool(v)) for v in items], np.uint8)
            return {"name": name, "type": "bool", "offset": blob.add(codes)}
        if all(isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool) for v in present):
            floats = np.array([np.nan if v is None else float(v) for v in items], np.float64)
            return {"name": name, "type": "float", "offset": blob.add(floats)}
    elif col.dtype.kind == "b":
        return {"name": name, "type": "bool", "offset": blob.add(col.astype(np.uint8))}
    elif col.dtype.kind in "iu":
        if len(col) == 0 or (col.min() >= _INT32[0] and col.max() <= _INT32[1]):
            return {"name": name, "type": "int", "offset": blob.add(col.astype("<i4"))}
        return {"name": name, "type": "float", "offset": blob.add(col.astype("<f8"))}
    elif col.dtype.kind == "f":
        return {"name": name, "type": "float", "offset": blob.add(col.astype("<f8"))}
    texts = [None if v is None or (isinstance(v, float) and np.isnan(v)) else str(v) for v in col.tolist()]
    values: dict[str | None, int] = {}
    codes = np.fromiter((values.setdefault(t, len(values)) for t in texts), np.int64, count=len(texts))
    width = 1 if len(values) <= 2**8 else 2 if len(values) <= 2**16 else 4
    dtype = {1: np.uint8, 2: "<u2", 4: "<u4"}[width]
    return {
        "name": name,
        "type": "text",
        "offset": blob.add(codes.astype(dtype)),
        "values": list(values),
        "width": width,
    }


def view_text(
    layers: Sequence[ViewLayer],
    *,
    name: str = "",
    attribution: str | None = None,
    crs: str = "",
    origin: Mapping | None = None,
    plan: str | None = None,
) -> str:
    """The text of ``city.view.js`` for ``layers`` (see the module notes); the same layers give the same text.

    Parameters
    ----------
    layers : sequence of ViewLayer
        In drawing order.
    name : str
        The city's name (the page's title).
    attribution : str, optional
        The data's licence notice, shown on the page.
    crs : str
        The planar frame (``EPSG:32631`` ...), for the record.
    origin : mapping, optional
        The city's origin, ``{"lat": .., "lon": .., "planar": [x, y]}``.
    plan : str, optional
        File name of the plan image shown below the 3D view (``preview.png``).
    """
    blob = _Blob()
    entries = []
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for lay in layers:
        pos = np.ascontiguousarray(lay.position, np.float32).reshape(-1, 3)
        idx = np.ascontiguousarray(lay.index, "<u4").reshape(-1, 3)
        feat = np.ascontiguousarray(lay.feature, "<f4").reshape(-1)
        if len(pos) != len(feat):
            raise ValueError(f"layer {lay.name}: {len(pos)} vertices but {len(feat)} feature rows")
        if len(pos):
            lo, hi = np.minimum(lo, pos.min(axis=0)), np.maximum(hi, pos.max(axis=0))
        idx, tile_rows = tiles(pos, idx, feat)
        entry = {
            "name": lay.name,
            "colour": [int(c) for c in lay.colour],
            "kind": lay.kind,
            "vertices": len(pos),
            "triangles": len(idx),
            "features": int(lay.features),
            "position": blob.add(pos.astype("<f4")),
            "index": blob.add(np.ascontiguousarray(idx, "<u4")),
            "feature": blob.add(feat),
            "tiles": tile_rows,
            "scale": round(_scale(lay, pos, idx, feat), 3),
            "columns": [],
        }
        for key, values in lay.columns.items():
            if len(values) != lay.features:
                raise ValueError(f"layer {lay.name}: column {key} has {len(values)} values for {lay.features} features")
            entry["columns"].append(_column(blob, key, values))
        entries.append(entry)
    bounds = [float(v) for v in np.concatenate([lo, hi])] if np.isfinite(lo).all() else [0.0] * 6
    home = _home(layers) or bounds
    doc = {
        "format": "sengine-view",
        "version": 1,
        "name": name,
        "attribution": attribution or "",
        "crs": crs,
        "origin": dict(origin or {}),
        "bounds": bounds,
        "home": home,
        "plan": plan,
        "layers": entries,
    }
    head = json.dumps(doc, sort_keys=True, separators=(",", ":"), ensure_ascii=True)
    # the base64 goes last, outside the JSON text, so that the head stays small to read
    texts = ",\n".join(f'"{t}"' for t in blob.base64(BIN_CHUNK))
    return f'window.SENGINE_VIEW = {head[:-1]},"bin":[{texts}]}};\n'


def write_page(out: str | Path) -> Path:
    """Copy the page (``index.html``, ``viewer.js``) into folder ``out``; return the page's path."""
    out = Path(out)
    for name in PAGE_FILES:
        shutil.copyfile(ASSETS / name, out / name)
    return out / "index.html"


def write_view(out: str | Path, layers: Sequence[ViewLayer], **meta) -> dict:
    """Write ``city.view.js`` (:func:`view_text`) and the page into folder ``out``; return counts.

    ``meta`` are :func:`view_text`'s keywords.
    """
    out = Path(out)
    text = view_text(layers, **meta)
    (out / DATA_FILE).write_text(text, encoding="ascii")
    write_page(out)
    counts = {lay.name: {"features": int(lay.features), "triangles": int(len(lay.index))} for lay in layers}
    log.info("wrote %s: %d layers, %.1f MB", out / DATA_FILE, len(counts), len(text) / 1e6)
    return counts


def _quiet_handler() -> type:
    """A request handler that logs at debug level (http.server imported here: a run that writes never serves)."""
    import http.server

    class _QuietHandler(http.server.SimpleHTTPRequestHandler):
        def log_message(self, format, *args):  # noqa: A002 (the standard library's name)
            log.debug("serve: " + format, *args)

    return _QuietHandler


def serve(out: str | Path, *, port: int = 0, host: str = "127.0.0.1") -> http.server.ThreadingHTTPServer:
    """An HTTP server of folder ``out`` on ``host`` (this machine only), started in a thread.

    ``port`` 0 takes a free port (see ``server.server_address``).  Stop it
    with ``server.shutdown()``.

    Raises
    ------
    ParameterError
        The port is taken or cannot be had.
    """
    import http.server

    handler = functools.partial(_quiet_handler(), directory=str(Path(out)))
    try:
        server = http.server.ThreadingHTTPServer((host, int(port)), handler)
    except OSError as err:
        raise ParameterError(f"cannot serve on {host}:{port}: {err.strerror or err}", where="--port") from None
    thread = threading.Thread(target=server.serve_forever, name="sengine-view", daemon=True)
    thread.start()
    return server
