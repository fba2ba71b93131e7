"""Image maps: read an image, place it on the city extent, sample and vectorize it.

skylineEngine (paper 002, §5.2) drives a synthetic city with images: a
district map (one colour per district), a land-use map (where nothing may be
built) and a height map (the skyline).  This module knows nothing about what
the colours mean; it only

* reads PNG, JPEG, TIFF, BMP ... with Pillow, in 1-, 8- and 16-bit greyscale,
  RGB(A) and palette modes (:func:`read_map`);
* places the image on the extent ``(xmin, ymin, xmax, ymax)`` in metres, with
  pixel row 0 along the **north** edge ``y = ymax`` (:class:`ImageMap`);
* samples it at points, vectorized over numpy arrays (:meth:`ImageMap.sample`,
  :meth:`ImageMap.fraction`);
* labels each pixel with the nearest colour of a legend (:func:`classify`) and
  turns the label image into polygons that share their borders exactly
  (:func:`vectorize`): the pixel-edge linework between different labels is
  noded, polygonized and then simplified as one *coverage*
  (``shapely.coverage_simplify``), so neighbouring regions keep a common
  border with no gap and no overlap.

Every problem a user can cause (missing or unreadable file, an aspect ratio
that disagrees with the city, a colour not in the legend) is a one-line
:class:`~sengine.errors.InputDataError` naming the file, and the configuration
line when the caller passes it as ``where``.

References
----------
.. [1] R. Ridorsa and G. Patow, "skylineEngine: an urban procedural modelling system",
   technical report, Geometry and Graphics Group, Universitat de Girona, 2011
   (the specification: paper 002 in shared/papers).
"""

from __future__ import annotations

import logging
import re
import stat
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import shapely

from ..errors import InputDataError
from .polygons import largest_share

__all__ = ["ImageMap", "read_map", "parse_colour", "colour_hex", "classify", "vectorize", "LOSSY_FORMATS"]

log = logging.getLogger(__name__)

#: Pillow format names whose pixels are only approximately the drawn colour.
LOSSY_FORMATS = frozenset({"JPEG", "MPO", "WEBP", "JPEG2000"})
MAX_PIXELS = 64_000_000  # an 8000 x 8000 map; a larger one is refused before it is decoded

_HEX_RE = re.compile(r"^#?([0-9a-fA-F]{6}|[0-9a-fA-F]{3})$")


@dataclass(frozen=True, eq=False)
class ImageMap:
    """An image placed on the city extent.

    Attributes
    ----------
    data : numpy.ndarray
        Pixels, shape ``(rows, cols)`` for greyscale (uint8, uint16, int32 or
        float32 as stored) or ``(rows, cols, 3)`` uint8 for colour.
    extent : tuple of float
        ``(xmin, ymin, xmax, ymax)`` in metres that the image covers; row 0
        lies along ``y = ymax`` (north), column 0 along ``x = xmin`` (west).
    src : pathlib.Path
        The file the image came from.
    where : str
        ``file:line`` of the configuration element, for error messages.
    mode : str
        Pillow mode of the file (``L``, ``I;16``, ``RGB``, ``P`` ...).
    format : str
        Pillow format name of the file (``PNG``, ``JPEG``, ``TIFF`` ...).
    full_scale : float
        The greyscale value meaning "white" (255, 65535, 1.0 ...).
    """

    data: np.ndarray
    extent: tuple[float, float, float, float]
    src: Path
    where: str = ""
    mode: str = ""
    format: str = ""
    full_scale: float = 255.0

    # -- geometry of the pixel grid ------------------------------------------
    @property
    def shape(self) -> tuple[int, int]:
        """``(rows, cols)`` of the image."""
        return int(self.data.shape[0]), int(self.data.shape[1])

    @property
    def pixel_size(self) -> tuple[float, float]:
        """Width and height of one pixel (m)."""
        rows, cols = self.shape
        xmin, ymin, xmax, ymax = self.extent
        return (xmax - xmin) / cols, (ymax - ymin) / rows

    @property
    def lossy(self) -> bool:
        """Whether the file format is lossy (JPEG ...): colours near borders are blended."""
        return self.format in LOSSY_FORMATS

    def edges(self) -> tuple[np.ndarray, np.ndarray]:
        """X of the ``cols + 1`` column edges and y of the ``rows + 1`` row edges (m).

        Row edge 0 is the north edge ``ymax``; the arrays are the only source
        of pixel-corner coordinates, so equal corners are equal floats.
        """
        rows, cols = self.shape
        xmin, ymin, xmax, ymax = self.extent
        xs = xmin + (xmax - xmin) * (np.arange(cols + 1) / cols)
        ys = ymax - (ymax - ymin) * (np.arange(rows + 1) / rows)
        xs[-1], ys[-1] = xmax, ymin
        return xs, ys

    def pixel_index(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """Column and row of the pixel holding each point, clipped to the image.

        Parameters
        ----------
        x, y : array_like of float
            Planar coordinates (m).

        Returns
        -------
        cols, rows : numpy.ndarray of int
        """
        rows, cols = self.shape
        xmin, ymin, xmax, ymax = self.extent
        x = np.asarray(x, dtype=float)
        y = np.asarray(y, dtype=float)
        c = np.floor((x - xmin) / (xmax - xmin) * cols).astype(np.int64)
        r = np.floor((ymax - y) / (ymax - ymin) * rows).astype(np.int64)
        return np.clip(c, 0, cols - 1), np.clip(r, 0, rows - 1)

    def pixel_centre(self, col, row) -> tuple[np.ndarray, np.ndarray]:
        """Planar coordinates (m) of pixel centres."""
        px, py = self.pixel_size
        xmin, _, _, ymax = self.extent
        return xmin + (np.asarray(col) + 0.5) * px, ymax - (np.asarray(row) + 0.5) * py

    # -- sampling ----------------------------------------------------------------
    def sample(self, x, y) -> np.ndarray:
        """The stored pixel value at each point (nearest pixel; clipped at the edges)."""
        c, r = self.pixel_index(x, y)
        return self.data[r, c]

    def grey(self) -> np.ndarray:
        """The image as float greyscale in ``[0, 1]``, shape ``(rows, cols)``.

        Colour images use ITU-R 601 luma (``0.299 R + 0.587 G + 0.114 B``).
        """
        d = self.data.astype(np.float64)
        if d.ndim == 3:
            d = d @ np.array([0.299, 0.587, 0.114])
        return np.clip(d / self.full_scale, 0.0, 1.0)

    def fraction(self, x, y, *, bilinear: bool = True) -> np.ndarray:
        """Greyscale value in ``[0, 1]`` at each point.

        With ``bilinear`` the four pixel centres around a point are blended,
        so a height map gives a smooth field rather than terraces.
        """
        g = self.grey()
        if not bilinear:
            c, r = self.pixel_index(x, y)
            return g[r, c]
        rows, cols = self.shape
        xmin, ymin, xmax, ymax = self.extent
        fx = (np.asarray(x, float) - xmin) / (xmax - xmin) * cols - 0.5
        fy = (ymax - np.asarray(y, float)) / (ymax - ymin) * rows - 0.5
        fx = np.clip(fx, 0.0, cols - 1.0)
        fy = np.clip(fy, 0.0, rows - 1.0)
        c0 = np.minimum(np.floor(fx).astype(np.int64), max(cols - 2, 0))
        r0 = np.minimum(np.floor(fy).astype(np.int64), max(rows - 2, 0))
        c1 = np.minimum(c0 + 1, cols - 1)
        r1 = np.minimum(r0 + 1, rows - 1)
        tx = fx - c0
        ty = fy - r0
        top = g[r0, c0] * (1 - tx) + g[r0, c1] * tx
        bot = g[r1, c0] * (1 - tx) + g[r1, c1] * tx
        return top * (1 - ty) + bot * ty

    def scaled(self, x, y, low: float, high: float, *, bilinear: bool = True) -> np.ndarray:
        """Greyscale mapped linearly onto ``[low, high]`` (black -> low, white -> high)."""
        return low + (high - low) * self.fraction(x, y, bilinear=bilinear)

    def label(self) -> str:
        """How error messages name the map: ``file:line: map 'name.png'``."""
        return f"map '{self.src.name}'"


# -- reading ----------------------------------------------------------------------
def read_map(
    src,
    extent: Sequence[float],
    *,
    where: str = "",
    colour: bool | None = None,
    aspect_tolerance: float = 0.01,
) -> ImageMap:
    """Read an image file and place it on ``extent``.

    Parameters
    ----------
    src : str or pathlib.Path or MapSpec
        The image file, or a plan's MapSpec (its ``src`` and ``where`` are used).
    extent : sequence of float
        ``(xmin, ymin, xmax, ymax)`` of the city (m).
    where : str
        ``file:line`` for error messages (taken from a MapSpec when omitted).
    colour : bool, optional
        ``True`` converts to RGB uint8 (district and land-use maps), ``False``
        to a single greyscale channel kept at its bit depth (height maps),
        ``None`` keeps greyscale as greyscale and everything else as RGB.
    aspect_tolerance : float
        Largest relative difference allowed between the image's and the
        extent's width / height ratios (1 = 100 %).

    Returns
    -------
    ImageMap

    Raises
    ------
    InputDataError
        The file is missing or unreadable, or its aspect ratio disagrees with
        the extent.
    """
    from PIL import Image, UnidentifiedImageError

    if hasattr(src, "src") and hasattr(src, "kind"):
        where = where or getattr(src, "where", "")
        src = src.src
    path = Path(src)
    name = f"map '{path}'"
    try:
        st = path.stat()
    except FileNotFoundError:
        raise InputDataError(f"{name}: file not found", where=where or None) from None
    except OSError as exc:
        raise InputDataError(f"{name}: cannot read the file ({exc.strerror})", where=where or None) from None
    if stat.S_ISDIR(st.st_mode):
        raise InputDataError(f"{name} is a folder, not an image file", where=where or None)
    if not stat.S_ISREG(st.st_mode):
        raise InputDataError(f"{name} is not a regular file (a pipe or device?)", where=where or None)
    try:
        bomb, Image.MAX_IMAGE_PIXELS = Image.MAX_IMAGE_PIXELS, None  # sengine checks the size itself, below
        try:
            im = Image.open(path)
        finally:
            Image.MAX_IMAGE_PIXELS = bomb
        with im:
            cols, rows = im.size
            if cols * rows > MAX_PIXELS:
                raise InputDataError(
                    f"{name}: the image is {cols}x{rows} px ({cols * rows / 1e6:.0f} Mpx, about "
                    f"{cols * rows * 3 / 1e9:.1f} GB decoded); the limit is {MAX_PIXELS / 1e6:.0f} Mpx",
                    where=where or None,
                )
            im.load()
            fmt = im.format or ""
            mode = im.mode
            data, full = _pixels(im, colour)
    except InputDataError:
        raise
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError, MemoryError, EOFError) as exc:
        raise InputDataError(f"{name}: cannot read the image ({exc})", where=where or None) from None
    rows, cols = data.shape[:2]
    if rows == 0 or cols == 0:
        raise InputDataError(f"{name}: the image is empty", where=where or None)
    xmin, ymin, xmax, ymax = (float(v) for v in extent)
    want = (xmax - xmin) / (ymax - ymin)
    have = cols / rows
    if abs(have - want) / want > aspect_tolerance:
        raise InputDataError(
            f"{name}: image is {cols}x{rows} px (width/height {have:.3f}) but the city is "
            f"{xmax - xmin:g}x{ymax - ymin:g} m (width/height {want:.3f}); the ratios must agree within "
            f"{aspect_tolerance:.0%}",
            where=where or None,
        )
    log.debug("read %s: %dx%d px, mode %s, format %s", path, cols, rows, mode, fmt)
    return ImageMap(data, (xmin, ymin, xmax, ymax), path, where, mode, fmt, full)


def _pixels(im, colour: bool | None) -> tuple[np.ndarray, float]:
    """Pixel array and greyscale full-scale value of a Pillow image."""
    mode = im.mode
    grey_modes = ("1", "L", "LA", "I", "I;16", "I;16L", "I;16B", "I;16N", "F")
    if mode == "P":
        # a palette image may be greyscale or colour; look at its palette
        im = im.convert("RGBA" if "transparency" in im.info else "RGB")
        mode = im.mode
    if colour is True or (colour is None and mode not in grey_modes):
        if mode in ("I", "I;16", "I;16L", "I;16B", "I;16N", "F"):
            g, full = _grey(im)
            g8 = np.clip(np.rint(g.astype(np.float64) / full * 255.0), 0, 255).astype(np.uint8)
            return np.repeat(g8[:, :, None], 3, axis=2), 255.0
        return np.asarray(im.convert("RGB"), dtype=np.uint8).copy(), 255.0
    if mode not in grey_modes:
        im = im.convert("L")
    return _grey(im)


def _grey(im) -> tuple[np.ndarray, float]:
    mode = im.mode
    if mode == "1":
        return np.asarray(im.convert("L"), dtype=np.uint8).copy(), 255.0
    if mode == "LA":
        im = im.convert("L")
        mode = "L"
    if mode == "L":
        return np.asarray(im, dtype=np.uint8).copy(), 255.0
    if mode.startswith("I;16"):
        return np.asarray(im).astype(np.uint16), 65535.0
    if mode == "I":
        a = np.asarray(im).astype(np.int64)
        full = 255.0 if a.size and a.max() <= 255 and a.min() >= 0 else 65535.0
        return a.astype(np.int32), full
    if mode == "F":
        a = np.asarray(im, dtype=np.float32).copy()
        return a, 1.0
    return np.asarray(im.convert("L"), dtype=np.uint8).copy(), 255.0


# -- colours ----------------------------------------------------------------------
def parse_colour(text: str, *, where: str = "") -> tuple[int, int, int]:
    """``"#d03030"``, ``"d03030"``, ``"#d33"`` or ``"208 48 48"`` -> ``(208, 48, 48)``."""
    s = str(text).strip()
    m = _HEX_RE.match(s)
    if m:
        h = m.group(1)
        if len(h) == 3:
            h = "".join(ch * 2 for ch in h)
        return int(h[0:2], 16), int(h[2:4], 16), int(h[4:6], 16)
    parts = s.replace(",", " ").split()
    if len(parts) == 3:
        try:
            vals = tuple(int(p) for p in parts)
        except ValueError:
            vals = ()
        if len(vals) == 3 and all(0 <= v <= 255 for v in vals):
            return vals  # type: ignore[return-value]
    raise InputDataError(f"colour {text!r} is not '#rrggbb', '#rgb' or 'r g b' (0-255)", where=where or None)


def colour_hex(rgb) -> str:
    """``(208, 48, 48)`` -> ``"#d03030"``."""
    r, g, b = (int(v) for v in rgb)
    return f"#{r:02x}{g:02x}{b:02x}"


def classify(
    img: ImageMap,
    colours: Sequence[Sequence[int]],
    *,
    tolerance: float | None = None,
    names: Sequence[str] | None = None,
    what: str = "legend",
) -> np.ndarray:
    """Label each pixel with the index of its legend colour.

    Parameters
    ----------
    img : ImageMap
        A colour map (greyscale maps are compared as grey RGB).
    colours : sequence of (r, g, b)
        The legend, 0-255 per channel.
    tolerance : float, optional
        Largest Euclidean RGB distance between a pixel and its legend colour.
        Default 0 for lossless files, 60 for lossy ones (JPEG).  In a lossy
        file the blended pixels along colour borders take their nearest
        legend colour (only a 3x3 patch of off-legend pixels is an error) and
        the labels are smoothed with a 3x3 majority filter, so compression
        noise leaves no specks.
    names : sequence of str, optional
        Names of the legend entries, quoted in the error message.
    what : str
        What the legend describes ("district rules" ...), for the message.

    Returns
    -------
    numpy.ndarray of int, shape (rows, cols)

    Raises
    ------
    InputDataError
        A pixel is farther than ``tolerance`` from every legend colour; the
        message names its colour and its pixel (x = column, y = row).
    """
    data = img.data
    if data.ndim == 2:
        g = np.clip(np.rint(img.grey() * 255.0), 0, 255).astype(np.uint8)
        data = np.repeat(g[:, :, None], 3, axis=2)
    legend = np.asarray(colours, dtype=np.int64).reshape(-1, 3)
    if tolerance is None:
        tolerance = 60.0 if img.lossy else 0.0
    rows, cols = data.shape[:2]
    # work on the distinct colours only: maps hold a handful of them
    flat = data.reshape(-1, 3).astype(np.int64)
    keys = (flat[:, 0] << 16) | (flat[:, 1] << 8) | flat[:, 2]
    uniq, inverse = np.unique(keys, return_inverse=True)
    urgb = np.stack([(uniq >> 16) & 255, (uniq >> 8) & 255, uniq & 255], axis=1)
    if len(legend) == 0:
        raise InputDataError(f"{img.label()}: no {what} to match its colours against", where=img.where or None)
    d2 = ((urgb[:, None, :] - legend[None, :, :]) ** 2).sum(axis=2)
    best = d2.argmin(axis=1)
    bad = np.sqrt(d2[np.arange(len(uniq)), best]) > tolerance + 1e-9
    if bad.any() and img.lossy:
        # compression blends colours along borders: a pixel off the legend is
        # an error only inside a 3x3 patch of such pixels
        from scipy.ndimage import binary_erosion

        patch = binary_erosion(bad[inverse.reshape(rows, cols)], np.ones((3, 3), bool))
        bad = np.zeros(len(uniq), bool)
        bad[np.unique(inverse.reshape(rows, cols)[patch])] = True
    if bad.any():
        counts = np.bincount(inverse.ravel(), minlength=len(uniq))
        worst = int(np.flatnonzero(bad)[np.argmax(counts[bad])])
        first = int(np.flatnonzero(inverse.ravel() == worst)[0])
        r, c = divmod(first, cols)
        known = ", ".join(
            colour_hex(col) + (f" {names[i]}" if names is not None and i < len(names) else "")
            for i, col in enumerate(legend)
        )
        nbad = int(counts[bad].sum())
        raise InputDataError(
            f"{img.label()}: colour {colour_hex(urgb[worst])} at pixel (x={c}, y={r}) is not in the {what} "
            f"({nbad} pixel{'s' if nbad != 1 else ''} match no colour within {tolerance:g}; known: {known})",
            where=img.where or None,
        )
    labels = best[inverse.ravel()].reshape(rows, cols)
    if img.lossy and len(legend) > 1:
        labels = _majority(labels, len(legend))
    return labels


def _majority(labels: np.ndarray, n: int) -> np.ndarray:
    """3x3 majority filter over a label image (ties keep the centre label)."""
    from scipy.ndimage import uniform_filter

    present = np.unique(labels)
    votes = np.stack([uniform_filter((labels == k).astype(np.float32), size=3, mode="nearest") for k in present])
    winner = present[votes.argmax(axis=0)]
    centre_votes = np.take_along_axis(votes, np.searchsorted(present, labels)[None], axis=0)[0]
    keep = centre_votes >= votes.max(axis=0) - 1e-6
    return np.where(keep, labels, winner)


# -- vectorizing ------------------------------------------------------------------
def vectorize(
    img: ImageMap,
    labels: np.ndarray,
    *,
    simplify: float = 1.0,
    grid_size: float = 0.0,
) -> dict[int, shapely.Geometry]:
    """Polygons of the regions of equal label, as one gap-free coverage.

    The borders between pixels of different labels (plus the image frame) are
    noded and polygonized into faces; each face takes the label under it.
    To lose the pixel staircase, the noded linework is cut into edges between
    junctions; each edge's pixel steps are replaced by its segments' midpoints
    (a staircase becomes a line within half a pixel of the drawn border,
    corners between two sides longer than 1.5 pixels stay) and
    the edge is simplified (Douglas-Peucker, ``simplify`` pixels) with its end
    points fixed.  Every border exists once, as one edge, so neighbouring
    regions keep exactly one shared border; the smoothed edges are noded and
    polygonized again, each new face takes the label of the pixel face it
    overlaps most, and the faces of each label are dissolved.

    Parameters
    ----------
    img : ImageMap
        Gives the pixel grid's placement on the extent.
    labels : numpy.ndarray of int, shape (rows, cols)
        A label per pixel (from :func:`classify`).
    simplify : float
        Simplification tolerance in pixels (0 keeps the pixel staircase).
    grid_size : float
        When positive, coordinates are snapped to this grid (m).

    Returns
    -------
    dict of int to shapely.Polygon or shapely.MultiPolygon
        Label -> region.  The regions' union is the extent; they do not overlap.
    """
    labels = np.asarray(labels)
    rows, cols = labels.shape
    xs, ys = img.edges()
    segs = [shapely.box(xs[0], ys[-1], xs[-1], ys[0]).exterior]
    # horizontal borders: between row r and r + 1, runs of differing columns
    r, c0, c1 = _runs(labels[:-1, :] != labels[1:, :])
    segs += list(shapely.linestrings(np.stack([xs[c0], ys[r + 1], xs[c1], ys[r + 1]], 1).reshape(-1, 2, 2)))
    c, r0, r1 = _runs((labels[:, :-1] != labels[:, 1:]).T)
    segs += list(shapely.linestrings(np.stack([xs[c + 1], ys[r0], xs[c + 1], ys[r1]], 1).reshape(-1, 2, 2)))
    lines = shapely.union_all(np.asarray(segs, dtype=object))
    faces = np.asarray(shapely.get_parts(shapely.polygonize([lines])), dtype=object)
    pts = shapely.point_on_surface(faces)
    face_label = labels[img.pixel_index(shapely.get_x(pts), shapely.get_y(pts))[::-1]]
    if simplify > 0 and len(faces) > 1:
        edges = np.asarray(shapely.get_parts(shapely.line_merge(lines)), dtype=object)
        # edges along the image frame stay as they are (they hold its corners)
        xy, idx = shapely.get_coordinates(edges, return_index=True)
        xmin, ymin, xmax, ymax = img.extent
        off = ~(
            np.isclose(xy[:, 0], xmin)
            | np.isclose(xy[:, 0], xmax)
            | np.isclose(xy[:, 1], ymin)
            | np.isclose(xy[:, 1], ymax)
        )
        inner = np.bincount(idx, weights=off, minlength=len(edges)) > 0
        smooth = edges.copy()
        smooth[inner] = shapely.simplify(
            _smooth_edges(edges[inner], img.extent, 1.5 * max(img.pixel_size)),
            simplify * max(img.pixel_size),
            preserve_topology=True,
        )
        noded = shapely.union_all(smooth)
        new = np.asarray(shapely.get_parts(shapely.polygonize([noded])), dtype=object)
        # each new face takes the label of the pixel face it overlaps most
        host = largest_share(new, faces)
        new_label = np.where(host >= 0, face_label[np.maximum(host, 0)], -1)
        faces, face_label = new[new_label >= 0], new_label[new_label >= 0]
    if grid_size > 0:
        faces = shapely.set_precision(faces, grid_size)
    out: dict[int, shapely.Geometry] = {}
    for k in np.unique(face_label):
        out[int(k)] = shapely.union_all(faces[face_label == k], grid_size=grid_size or None)
    log.debug("vectorized %s: %d faces into %d regions", img.src.name, len(faces), len(out))
    return out


def _smooth_edges(edges: np.ndarray, extent, corner: float) -> np.ndarray:
    """Replace the staircase vertices of each edge by its segments' midpoints.

    A vertex between two segments longer than ``corner`` (m) is a drawn
    corner and stays; a vertex next to a short segment is a pixel step and is
    replaced by the midpoints of its segments, so a staircase becomes a line
    within half a pixel of the drawn border.  The edge's end points (the
    junctions shared with other edges) and every vertex on the image frame
    stay too, so neighbouring faces still meet exactly.
    """
    xmin, ymin, xmax, ymax = extent
    out = []
    for e in edges:
        xy = shapely.get_coordinates(e)
        if len(xy) < 3:
            out.append(e)
            continue
        closed = bool(np.all(xy[0] == xy[-1]))
        seg = np.hypot(*(xy[1:] - xy[:-1]).T)
        mids = (xy[:-1] + xy[1:]) / 2.0
        on_frame = (
            np.isclose(xy[:, 0], xmin)
            | np.isclose(xy[:, 0], xmax)
            | np.isclose(xy[:, 1], ymin)
            | np.isclose(xy[:, 1], ymax)
        )
        keep = np.zeros(len(xy), bool)
        keep[1:-1] = on_frame[1:-1] | ((seg[:-1] > corner) & (seg[1:] > corner))
        if closed:
            keep[0] = on_frame[0] | ((seg[-1] > corner) & (seg[0] > corner))
        else:
            keep[0] = keep[-1] = True
        pts = [xy[0]] if keep[0] else []
        for i in range(len(seg)):
            pts.append(mids[i])
            if i + 1 < len(xy) - 1 and keep[i + 1]:
                pts.append(xy[i + 1])
        if not closed:
            pts.append(xy[-1])
        else:
            pts.append(pts[0])
        out.append(shapely.linestrings(np.asarray(pts)))
    arr = np.empty(len(out), dtype=object)
    arr[:] = out
    return arr


def _runs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Row, first column and one-past-last column of each run of True in ``mask``."""
    padded = np.zeros((mask.shape[0], mask.shape[1] + 2), dtype=np.int8)
    padded[:, 1:-1] = mask
    d = np.diff(padded, axis=1)
    row, start = np.nonzero(d == 1)
    _, end = np.nonzero(d == -1)
    return row, start, end
