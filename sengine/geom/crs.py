"""Planar frames and WGS84: the city's local metric projection and its inverse.

Every layer is in metres in a planar frame named by ``layer.meta["crs"]``, a
string pyproj understands.  A synthetic city uses a local transverse Mercator
centred on its geographic origin (:func:`local_crs`), so planar ``(0, 0)`` is
the origin's latitude and longitude; an OSM city uses a UTM zone
(:func:`utm_crs`).  Exporters go back to WGS84 longitude / latitude
(:func:`to_lonlat`) for RFC 7946 GeoJSON and OSM XML.

Transformers are cached per CRS pair: building one costs milliseconds, using
one on an ``(n, 2)`` array costs microseconds per thousand points.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache

import numpy as np
from pyproj import CRS, Transformer

__all__ = [
    "local_crs",
    "utm_crs",
    "to_lonlat",
    "from_lonlat",
    "reproject",
    "registered_frame",
    "layer_crs",
    "output_crs",
    "parse_crs_option",
    "is_geographic",
    "WGS84",
]

WGS84 = "EPSG:4326"


def local_crs(origin: tuple[float, float]) -> str:
    """The local transverse Mercator frame whose ``(0, 0)`` is ``origin``.

    Parameters
    ----------
    origin : tuple of float
        ``(lat, lon)`` in degrees (WGS84).

    Returns
    -------
    str
        A PROJ string, metres, y pointing north.
    """
    lat, lon = (float(v) for v in origin)
    if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
        raise ValueError(f"origin (lat, lon) = ({lat}, {lon}) is outside [-90, 90] x [-180, 180]")
    return f"+proj=tmerc +lat_0={lat:.9g} +lon_0={lon:.9g} +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs"


def utm_crs(lat: float, lon: float) -> str:
    """The WGS84 UTM zone holding ``(lat, lon)`` as ``"EPSG:326zz"`` / ``"EPSG:327zz"``."""
    zone = int((float(lon) + 180.0) // 6.0) % 60 + 1
    return f"EPSG:{32600 + zone if float(lat) >= 0 else 32700 + zone}"


@lru_cache(maxsize=32)
def _transformer(src: str, dst: str) -> Transformer:
    return Transformer.from_crs(CRS.from_user_input(src), CRS.from_user_input(dst), always_xy=True)


def _apply(tr: Transformer) -> Callable[[np.ndarray], np.ndarray]:
    def f(xy: np.ndarray) -> np.ndarray:
        xy = np.asarray(xy, dtype=np.float64)
        if xy.size == 0:
            return xy.reshape(-1, 2)
        x, y = tr.transform(xy[:, 0], xy[:, 1])
        return np.column_stack([x, y])

    return f


def to_lonlat(crs: str) -> Callable[[np.ndarray], np.ndarray]:
    """A function mapping planar ``(n, 2)`` arrays in ``crs`` to WGS84 ``(lon, lat)``."""
    return _apply(_transformer(str(crs), WGS84))


def from_lonlat(crs: str) -> Callable[[np.ndarray], np.ndarray]:
    """A function mapping WGS84 ``(lon, lat)`` ``(n, 2)`` arrays to planar ``crs``."""
    return _apply(_transformer(WGS84, str(crs)))


def reproject(src: str, dst: str) -> Callable[[np.ndarray], np.ndarray]:
    """A function mapping ``(n, 2)`` arrays from frame ``src`` to frame ``dst``.

    When the frames are the same it is the identity, and says so: its
    attribute ``identity`` is True (writers then skip the work).
    """
    if str(src) == str(dst):

        def same(xy: np.ndarray) -> np.ndarray:
            return np.asarray(xy, dtype=np.float64).reshape(-1, 2)

        same.identity = True
        return same
    return _apply(_transformer(str(src), str(dst)))


def is_geographic(crs: str) -> bool:
    """Whether ``crs`` has angular (degree) coordinates, like WGS84."""
    return bool(_crs(str(crs)).is_geographic)


@lru_cache(maxsize=32)
def _crs(text: str) -> CRS:
    return CRS.from_user_input(text)


def parse_crs_option(text: str) -> str:
    """Check an output CRS option: ``utm``, ``wgs84`` or ``EPSG:n`` (any code PROJ knows).

    Returns the normalised option (``"utm"``, ``"wgs84"`` or ``"EPSG:n"``).

    Raises
    ------
    ValueError
        With a one-line reason.
    """
    t = str(text).strip()
    if t.lower() in ("utm", "wgs84"):
        return t.lower()
    if t.lower() in ("epsg:4326", "4326"):
        return "wgs84"
    head, _, code = t.partition(":")
    if head.lower() != "epsg" or not code.strip().isdigit():
        raise ValueError(f"{text!r} is not utm, wgs84 or EPSG:<code>")
    try:
        crs = _crs(f"EPSG:{int(code)}")
    except Exception:  # pyproj.exceptions.CRSError
        raise ValueError(f"EPSG:{int(code)} is not a coordinate reference system PROJ knows") from None
    if not (crs.is_projected or crs.is_geographic):
        raise ValueError(f"EPSG:{int(code)} is neither a projected nor a geographic 2D frame")
    return f"EPSG:{int(code)}"


def output_crs(option: str | None, crs: str, *, default: str = "utm") -> str:
    """The frame an output is written in.

    Parameters
    ----------
    option : str or None
        ``"utm"`` (the city's projected frame with an EPSG code: an OSM
        city's UTM zone, or the UTM zone of a synthetic city's origin),
        ``"wgs84"`` (EPSG:4326, lon / lat), ``"EPSG:n"``; None for ``default``.
    crs : str
        The layer's planar frame.
    default : str
        The option used when ``option`` is None.

    Returns
    -------
    str
        ``"EPSG:n"``.
    """
    option = parse_crs_option(option or default)
    if option == "wgs84":
        return WGS84
    if option == "utm":
        code = _crs(str(crs)).to_epsg()
        if code and _crs(str(crs)).is_projected:
            return f"EPSG:{code}"
        lon, lat = to_lonlat(crs)(np.zeros((1, 2)))[0]
        return utm_crs(lat, lon)
    return option


def registered_frame(crs: str, xy: np.ndarray) -> tuple[int, np.ndarray]:
    """Planar points in a frame that has an EPSG code, for formats that can only name one.

    Parameters
    ----------
    crs : str
        The points' planar frame.
    xy : ndarray (n, 2)
        Points (m).

    Returns
    -------
    code : int
        ``crs``'s own EPSG code when it has one (UTM), else that of the UTM
        zone holding the frame's origin (a synthetic city's local transverse
        Mercator has none).
    xy : ndarray (n, 2)
        The points in that frame (m): ``xy`` itself, or reprojected.
    """
    code = CRS.from_user_input(crs).to_epsg()
    if code:
        return int(code), xy
    lon, lat = to_lonlat(crs)(np.zeros((1, 2)))[0]
    utm = utm_crs(lat, lon)
    return int(utm.split(":")[1]), _apply(_transformer(str(crs), utm))(xy)


def layer_crs(meta: dict | None, origin: tuple[float, float]) -> str:
    """The planar CRS of a layer: ``meta["crs"]``, else the local frame at ``origin``.

    Parameters
    ----------
    meta : dict or None
        The layer's ``meta``.
    origin : (float, float)
        Latitude and longitude (deg) of the city's origin, used when the
        layer names no CRS.
    """
    crs = (meta or {}).get("crs")
    if crs:
        return str(crs)
    return local_crs(origin)
