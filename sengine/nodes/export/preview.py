"""``preview.png``: a plan view of the city, buildings coloured by height.

Drawn with Pillow's ImageDraw into 8-bit index layers that are composited
with numpy, then saved as a palette PNG (small, and no time chunk: the same
layers give the same bytes).  Layers from bottom to top: water, streets,
sidewalks, blocks, lots (with their outlines), parks, buildings (a colour
ramp over height; those of the map, ``source`` ``"osm"``, outlined), roads
(centre lines); bridge decks over the water and trees as dots of their
crown's width over the buildings.  A footer holds the height legend, a scale
bar and the layer swatches; the map's corners the city's name and a north
arrow (true north: in a UTM frame it leans by the meridian convergence, a
degree or two).

The view is framed on the city's streets, blocks, lots and buildings (and
the plan's extent for a synthetic city): parks and water that reach beyond
them (a large park relation of an OSM extract) are cut at the frame rather
than leaving the streets in a corner of the picture.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import shapely
from PIL import Image, ImageDraw, ImageFont

from sengine.layer import Layer

from .gltf import COLOURS
from .mesh import ring_arrays

__all__ = ["render", "write_preview", "frame", "city_title", "PALETTE", "ROADS_INDEX", "ramp"]

log = logging.getLogger(__name__)

#: Drawing order; trees are dots of their crown's size, bridges decks over the water.
_ORDER = ("water", "streets", "sidewalks", "blocks", "lots", "parks", "bridges", "buildings", "vegetation", "roads")
_INDEXED = (
    "water",
    "streets",
    "sidewalks",
    "blocks",
    "lots",
    "parks",
    "buildings",
    "roads",
    "bridges",
    "vegetation",
    "courtyards",
)
#: Patios (parks of level ``patio``: courtyards and rear yards, 001 §3.2) are private open space, not
#: public parks: drawn paler, so that a city with its courtyards on does not read as one park.
_COURTYARD = (196, 214, 170)
_BACKGROUND = (250, 250, 247)
_INK = (30, 30, 30)
_LOT_EDGE = (196, 188, 170)
_MAP_EDGE = (70, 70, 70)
# palette: 0 background, 1 ink, 2 white, 3 lot edges, 4 map buildings' edges, 8.. layers, 64..127 height ramp
_FIXED = {"background": 0, "ink": 1, "white": 2, "lot_edge": 3, "map_edge": 4}
_LAYER_INDEX = {name: 8 + i for i, name in enumerate(_INDEXED)}
ROADS_INDEX = _LAYER_INDEX["roads"]
_RAMP0, _RAMP_N = 64, 64
_RAMP_STOPS = np.array([(255, 240, 170), (253, 190, 90), (240, 110, 50), (190, 40, 70), (100, 20, 90)], float)


def ramp(t: np.ndarray) -> np.ndarray:
    """Colours (uint8 RGB) of the height ramp at ``t`` in ``[0, 1]``."""
    t = np.clip(np.asarray(t, float), 0.0, 1.0) * (len(_RAMP_STOPS) - 1)
    i = np.minimum(t.astype(int), len(_RAMP_STOPS) - 2)
    f = (t - i)[..., None]
    return np.rint(_RAMP_STOPS[i] * (1 - f) + _RAMP_STOPS[i + 1] * f).astype(np.uint8)


def _palette() -> np.ndarray:
    pal = np.zeros((256, 3), np.uint8)
    pal[0], pal[1], pal[2], pal[3], pal[4] = _BACKGROUND, _INK, (255, 255, 255), _LOT_EDGE, _MAP_EDGE
    for name, idx in _LAYER_INDEX.items():
        pal[idx] = _COURTYARD if name == "courtyards" else COLOURS[name]
    pal[_RAMP0 : _RAMP0 + _RAMP_N] = ramp(np.linspace(0, 1, _RAMP_N))
    return pal


PALETTE = _palette()


def _nice(x: float) -> float:
    """The largest 1, 2 or 5 times a power of ten not above ``x``."""
    if x <= 0:
        return 1.0
    e = 10.0 ** np.floor(np.log10(x))
    return float(max(m * e for m in (1, 2, 5) if m * e <= x))


#: Layers that frame the view (the city proper); the others are drawn where they fall inside it.
FRAMING = ("roads", "streets", "sidewalks", "blocks", "lots", "buildings")


def frame(layers: Mapping[str, Layer], extent=None) -> tuple[float, float, float, float]:
    """The planar bounds ``(xmin, ymin, xmax, ymax)`` the view shows.

    The bounds of the :data:`FRAMING` layers and ``extent``; when there are
    none of those, of every layer.
    """
    framing = [shapely.total_bounds(v.geometry) for k, v in layers.items() if k in FRAMING and len(v)]
    if extent is not None:
        framing.append(np.asarray(extent, float))
    bounds = [b for b in framing if np.all(np.isfinite(b))]
    if not bounds:
        bounds = [shapely.total_bounds(v.geometry) for v in layers.values() if len(v)]
        bounds = [b for b in bounds if np.all(np.isfinite(b))]
    if not bounds:
        return (0.0, 0.0, 1.0, 1.0)
    b = np.array(bounds)
    return (float(b[:, 0].min()), float(b[:, 1].min()), float(b[:, 2].max()), float(b[:, 3].max()))


def city_title(name: str) -> str:
    """A city's name for a title: a file name loses its extensions (``liege_streets.osm.pbf`` -> ``liege_streets``)."""
    return re.sub(r"(\.(osm|pbf|bz2|gz|xml|o5m))+$", "", str(name or "").strip(), flags=re.IGNORECASE) or "city"


def _draw_polygons(draw: ImageDraw.ImageDraw, rings, to_px, values, outline: int | None = None) -> None:
    """Fill polygons (holes filled with 0) with a per-feature index value."""
    if rings.n_polys == 0:
        return
    pix = np.rint(to_px(rings.xy)).astype(np.int64).ravel().tolist()
    rs = rings.ring_start.tolist()
    pr = rings.poly_ring.tolist()
    vals = np.asarray(values)
    vals = (vals[rings.feature] if vals.ndim else np.full(rings.n_polys, int(vals))).tolist()
    polygon = draw.polygon
    for p in range(rings.n_polys):
        r0, r1 = pr[p], pr[p + 1]
        polygon(pix[2 * rs[r0] : 2 * rs[r0 + 1]], fill=vals[p], outline=outline)
        for r in range(r0 + 1, r1):
            polygon(pix[2 * rs[r] : 2 * rs[r + 1]], fill=0, outline=outline)


def _draw_lines(draw: ImageDraw.ImageDraw, geoms: np.ndarray, to_px, value: int, widths) -> None:
    geoms = np.asarray(geoms, dtype=object)
    parts, feat = shapely.get_parts(geoms, return_index=True)
    polys = shapely.get_type_id(parts) == 3
    if polys.any():  # polygon outlines
        rings, ri = shapely.get_rings(parts[polys], return_index=True)
        parts = np.concatenate([parts[~polys], rings])
        feat = np.concatenate([feat[~polys], feat[polys][ri]])
    coords, idx = shapely.get_coordinates(parts, return_index=True)
    if len(coords) == 0:
        return
    pix = np.rint(to_px(coords)).astype(np.int64).ravel().tolist()
    starts = np.concatenate([[0], np.cumsum(np.bincount(idx, minlength=len(parts)))]).tolist()
    w = np.broadcast_to(np.asarray(widths), (len(geoms),))[feat].tolist()
    line = draw.line
    for k in range(len(parts)):
        a, b = starts[k], starts[k + 1]
        if b - a >= 2:
            line(pix[2 * a : 2 * b], fill=value, width=int(w[k]))


def _draw_points(draw: ImageDraw.ImageDraw, geoms: np.ndarray, to_px, value: int, diameter) -> None:
    """Dots of ``diameter`` px (one pixel at least) at points."""
    pix = to_px(shapely.get_coordinates(geoms))
    r = np.maximum(np.nan_to_num(np.asarray(diameter, float)) / 2, 0.5)
    small = r < 1.0
    if small.any():
        draw.point(np.rint(pix[small]).astype(np.int64).ravel().tolist(), fill=value)
    box = np.column_stack([pix - r[:, None], pix + r[:, None]])[~small].tolist()
    ellipse = draw.ellipse
    for b in box:
        ellipse(b, fill=value)


def render(
    layers: Mapping[str, Layer],
    *,
    size: int = 1600,
    extent=None,
    attribution: str | None = None,
    title: str | None = None,
    north: float = 0.0,
) -> Image.Image:
    """The plan view as a palette image, ``size`` px on its long side (plus a footer).

    Parameters
    ----------
    layers : mapping of str to Layer
        Layers by name (``roads``, ``streets``, ``sidewalks``, ``blocks``,
        ``lots``, ``parks``, ``buildings``, ``water``); unknown names are ignored.
    size : int
        Pixels along the longer side of the map.
    extent : tuple of float, optional
        ``(xmin, ymin, xmax, ymax)`` (m) to show at least (the city extent);
        the view also covers every layer's bounds.
    attribution : str, optional
        The data's licence notice, written in the footer's right corner.
    title : str, optional
        The city's name, written in the map's top left corner.
    north : float
        Where true north points, in degrees clockwise from the top of the
        picture (the planar frame's grid north); the arrow in the top right
        corner shows it.
    """
    layers = {k: v for k, v in layers.items() if v is not None and len(v)}
    xmin, ymin, xmax, ymax = frame(layers, extent)
    span = max(xmax - xmin, ymax - ymin, 1e-9)
    pad = 10
    scale = (size - 2 * pad) / span
    w = int(np.ceil((xmax - xmin) * scale)) + 2 * pad
    h = int(np.ceil((ymax - ymin) * scale)) + 2 * pad

    def to_px(xy: np.ndarray) -> np.ndarray:
        return np.column_stack([(xy[:, 0] - xmin) * scale + pad, (ymax - xy[:, 1]) * scale + pad])

    canvas = Image.new("L", (w, h), 0)
    hmin = hmax = 0.0
    has_map = has_courtyards = False
    for name in _ORDER:
        lay = layers.get(name)
        if lay is None:
            continue
        geoms = lay.geometry
        types = shapely.get_type_id(geoms)
        polys = np.isin(types, (3, 6))
        lines = np.isin(types, (1, 2, 5))
        if polys.any():
            rings = ring_arrays(geoms[polys])
            holes = len(rings.ring_start) - 1 > rings.n_polys
            # polygons with holes go through their own layer so the holes show what lies below
            img = Image.new("L", (w, h), 0) if holes else canvas
            draw = ImageDraw.Draw(img)
            if name == "buildings" and "height" in lay.attrs:
                hts = np.nan_to_num(np.asarray(lay["height"], float))
                hmin, hmax = float(hts.min()), float(hts.max())
                t = (hts - hmin) / (hmax - hmin) if hmax > hmin else np.full(len(hts), 0.5)
                vals = _RAMP0 + np.minimum((t * _RAMP_N).astype(int), _RAMP_N - 1)
                mapped = np.asarray(lay.get("source", np.full(len(lay), ""))).astype(str) == "osm"
                if mapped.any():  # the map's own buildings outlined, over the generated ones
                    has_map = True
                    for sel, edge in ((polys & ~mapped, None), (polys & mapped, _FIXED["map_edge"])):
                        _draw_polygons(draw, ring_arrays(geoms[sel]), to_px, vals[sel], outline=edge)
                else:
                    _draw_polygons(draw, rings, to_px, vals[polys])
            else:
                edge = _FIXED["lot_edge"] if name == "lots" else None
                value = np.full(int(polys.sum()), _LAYER_INDEX.get(name, _FIXED["ink"]))
                if name == "parks" and "level" in lay.attrs:
                    patio = np.asarray(lay["level"]).astype(str)[polys] == "patio"
                    value[patio] = _LAYER_INDEX["courtyards"]
                    has_courtyards |= bool(patio.any())
                _draw_polygons(draw, rings, to_px, value, outline=edge)
            if holes:
                canvas.paste(img, mask=img.point(lambda v: 255 if v else 0))
        points = types == 0
        if points.any():  # trees: a dot as wide as the crown
            crown = np.asarray(lay.get("crown", np.full(len(lay), 6.0)), float)[points]
            _draw_points(
                ImageDraw.Draw(canvas), geoms[points], to_px, _LAYER_INDEX.get(name, _FIXED["ink"]), crown * scale
            )
        if lines.any():
            if name == "roads" and "streets" not in layers and "width" in lay.attrs:
                widths = np.maximum(1, np.rint(np.nan_to_num(np.asarray(lay["width"], float))[lines] * scale))
            elif "major" in lay.attrs:
                widths = np.where(np.asarray(lay["major"], bool)[lines], 2, 1)
            else:
                widths = 1
            _draw_lines(ImageDraw.Draw(canvas), geoms[lines], to_px, _LAYER_INDEX.get(name, _FIXED["ink"]), widths)
    canvas = np.asarray(canvas)
    image = Image.fromarray(np.vstack([canvas, np.zeros((64, w), np.uint8)]), "P")
    image.putpalette(PALETTE.ravel().tolist())
    present = [n for n in _ORDER if n in layers] + (["courtyards"] if has_courtyards else [])
    _footer(image, h, w, scale, hmin, hmax, present, map_buildings=has_map)
    _north_arrow(image, w, north)
    if title:
        _title(image, title)
    if attribution:
        draw = ImageDraw.Draw(image)
        draw.text((w - 8, h + 60), attribution, fill=_FIXED["ink"], font=ImageFont.load_default(size=12), anchor="rd")
    return image


def _title(image: Image.Image, title: str) -> None:
    """The city's name in a white box in the map's top left corner."""
    draw = ImageDraw.Draw(image)
    font = ImageFont.load_default(size=22)
    x0, y0, x1, y1 = draw.textbbox((18, 16), title, font=font)
    draw.rectangle([x0 - 8, y0 - 6, x1 + 8, y1 + 6], fill=_FIXED["white"], outline=_FIXED["ink"])
    draw.text((18, 16), title, fill=_FIXED["ink"], font=font)


def _north_arrow(image: Image.Image, w: int, north: float) -> None:
    """A north arrow (a half-filled dart and an N) in the map's top right corner, turned ``north`` degrees."""
    draw = ImageDraw.Draw(image)
    cx, cy, r = w - 40, 48, 22
    a = np.radians(north)
    c, s = np.cos(a), np.sin(a)

    def at(x: float, y: float) -> tuple[float, float]:  # (x right, y up) around the centre, turned clockwise
        return (cx + x * c + y * s, cy - (-x * s + y * c))

    draw.ellipse([cx - r - 6, cy - r - 6, cx + r + 6, cy + r + 6], fill=_FIXED["white"], outline=_FIXED["ink"])
    tip, tail, left, right = at(0, r), at(0, -r * 0.55), at(-r * 0.5, -r * 0.8), at(r * 0.5, -r * 0.8)
    draw.polygon([tip, left, tail], fill=_FIXED["ink"], outline=_FIXED["ink"])
    draw.polygon([tip, right, tail], fill=_FIXED["white"], outline=_FIXED["ink"])
    font = ImageFont.load_default(size=14)
    nx, ny = at(0, r + 15)
    draw.text((nx, ny), "N", fill=_FIXED["ink"], font=font, anchor="mm")


def _footer(
    image: Image.Image,
    top: int,
    w: int,
    scale: float,
    hmin: float,
    hmax: float,
    present: list,
    *,
    map_buildings: bool = False,
) -> None:
    draw = ImageDraw.Draw(image)
    font = ImageFont.load_default(size=13)
    ink = _FIXED["ink"]
    draw.line([(0, top), (w, top)], fill=ink)
    y = top + 14
    x = 12
    # scale bar: a round length about a sixth of the width
    metres = _nice((w / 6) / scale)
    px = int(round(metres * scale))
    draw.rectangle([x, y + 10, x + px, y + 16], fill=ink)
    label = f"{metres:g} m" if metres < 1000 else f"{metres / 1000:g} km"
    draw.text((x, y + 20), label, fill=ink, font=font)
    x += max(px, 60) + 30
    if "buildings" in present:
        bar = 160
        for i in range(bar):
            draw.line([(x + i, y + 8), (x + i, y + 18)], fill=_RAMP0 + min(_RAMP_N - 1, i * _RAMP_N // bar))
        draw.rectangle([x, y + 8, x + bar, y + 18], outline=ink)
        draw.text((x, y + 20), f"{hmin:.0f} m", fill=ink, font=font)
        draw.text((x + bar, y + 20), f"{hmax:.0f} m", fill=ink, font=font, anchor="ra")
        draw.text((x, y - 8), "building height", fill=ink, font=font)
        x += bar + 30
        if map_buildings:
            draw.rectangle([x, y + 8, x + 14, y + 20], fill=_RAMP0 + _RAMP_N // 4, outline=_FIXED["map_edge"], width=2)
            draw.text((x + 18, y + 7), "from the map", fill=ink, font=font)
            x += 24 + int(draw.textlength("from the map", font=font)) + 12
    for name in present:
        if name == "buildings" or x > w - 90:
            continue
        draw.rectangle([x, y + 8, x + 14, y + 20], fill=_LAYER_INDEX[name], outline=ink)
        draw.text((x + 18, y + 7), name, fill=ink, font=font)
        x += 24 + int(draw.textlength(name, font=font)) + 12


def write_preview(
    path: str | Path,
    layers: Mapping[str, Layer],
    *,
    size: int = 1600,
    extent=None,
    attribution: str | None = None,
    title: str | None = None,
    north: float = 0.0,
) -> tuple[int, int]:
    """Render and save ``preview.png`` (see :func:`render`); return its pixel size."""
    image = render(layers, size=size, extent=extent, attribution=attribution, title=title, north=north)
    image.save(Path(path), format="PNG", optimize=False, compress_level=1)
    log.info("wrote %s: %dx%d px", path, *image.size)
    return image.size
