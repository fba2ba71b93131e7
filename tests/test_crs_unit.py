"""sengine.geom.crs, function by function, with values worked out by hand.

UTM zones from the 6-degree rule, the central meridian of a zone at easting 500 000 m, a
local transverse Mercator whose (0, 0) is its origin, the option parser's one-line errors:
for the mutation run of docs/mutation.md.
"""

from __future__ import annotations

import numpy as np
import pytest

from sengine.geom.crs import (
    WGS84,
    from_lonlat,
    is_geographic,
    layer_crs,
    local_crs,
    output_crs,
    parse_crs_option,
    registered_frame,
    reproject,
    to_lonlat,
    utm_crs,
)


def test_local_crs_string_and_bounds():
    assert local_crs((40.7, -74.0)) == (
        "+proj=tmerc +lat_0=40.7 +lon_0=-74 +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs"
    )
    assert "+lat_0=50.6123457 +lon_0=5.57" in local_crs(("50.61234567891", 5.57))  # 9 significant digits
    for ok in ((90.0, 180.0), (-90.0, -180.0)):  # inclusive bounds
        assert local_crs(ok).startswith("+proj=tmerc")
    for bad in ((90.001, 0.0), (-90.001, 0.0), (0.0, 180.001), (0.0, -180.001)):
        with pytest.raises(ValueError) as e:
            local_crs(bad)
        assert str(e.value) == f"origin (lat, lon) = ({bad[0]}, {bad[1]}) is outside [-90, 90] x [-180, 180]"


def test_utm_zones_by_hand():
    assert utm_crs(50.63, 5.57) == "EPSG:32631"  # Liège: floor(185.57 / 6) = 30, zone 31
    assert utm_crs(-33.9, 18.4) == "EPSG:32734"  # Cape Town: zone 34 south
    assert utm_crs(40.7, -74.0) == "EPSG:32618"  # New York: floor(106 / 6) = 17, zone 18
    assert utm_crs(0.0, 0.0) == "EPSG:32631"  # the equator is north
    assert utm_crs("-33.9", "18.4") == "EPSG:32734"  # strings as a config gives them: both converted
    assert utm_crs(-1e-9, 0.0) == "EPSG:32731"
    assert utm_crs(10.0, 6.0) == "EPSG:32632"  # a zone's west edge belongs to it
    assert utm_crs(10.0, 5.999) == "EPSG:32631"
    assert utm_crs(10.0, -180.0) == "EPSG:32601" and utm_crs(10.0, 180.0) == "EPSG:32601"  # wraps round
    assert utm_crs(10.0, 179.9) == "EPSG:32660"


def test_transforms_by_hand():
    # a zone's central meridian on the equator is at easting 500 000 m, northing 0
    fwd = from_lonlat("EPSG:32631")
    xy = fwd(np.array([[3.0, 0.0], [3.0, 1.0]]))
    assert xy.shape == (2, 2) and xy.dtype == np.float64
    assert np.allclose(xy[0], [500000.0, 0.0], atol=1e-6)
    assert abs(xy[1, 0] - 500000.0) < 1e-6 and 110_000 < xy[1, 1] < 111_000  # one degree of latitude
    back = to_lonlat("EPSG:32631")(xy)
    assert np.allclose(back, [[3.0, 0.0], [3.0, 1.0]], atol=1e-9)
    # a local frame's (0, 0) is its origin; 1 km east is east
    crs = local_crs((50.63, 5.57))
    ll = to_lonlat(crs)(np.array([[0.0, 0.0], [1000.0, 0.0], [0.0, 1000.0]]))
    assert np.allclose(ll[0], [5.57, 50.63], atol=1e-12)
    assert ll[1, 0] > 5.57 and abs(ll[1, 1] - 50.63) < 1e-3
    assert ll[2, 1] > 50.63 and abs(ll[2, 0] - 5.57) < 1e-9
    assert np.allclose(from_lonlat(crs)(ll), [[0, 0], [1000, 0], [0, 1000]], atol=1e-6)
    empty = to_lonlat(crs)(np.zeros((0, 2)))
    assert empty.shape == (0, 2)
    assert to_lonlat(crs)([]).shape == (0, 2)
    assert to_lonlat(crs)(np.zeros((0, 2), np.int64)).dtype == np.float64  # integers in, floats out, even empty
    assert to_lonlat(crs)([[0, 0]]).dtype == np.float64


def test_reproject():
    same = reproject("EPSG:32631", "EPSG:32631")
    assert same.identity is True
    out = same([1, 2, 3, 4])
    assert out.tolist() == [[1.0, 2.0], [3.0, 4.0]] and out.dtype == np.float64
    other = reproject("EPSG:32631", WGS84)
    assert not hasattr(other, "identity")
    assert np.allclose(other(np.array([[500000.0, 0.0]])), [[3.0, 0.0]], atol=1e-9)
    assert np.allclose(reproject(WGS84, "EPSG:32631")(np.array([[3.0, 0.0]])), [[500000.0, 0.0]], atol=1e-6)
    assert WGS84 == "EPSG:4326"


def test_is_geographic():
    assert is_geographic("EPSG:4326") is True
    assert is_geographic("EPSG:32631") is False
    assert is_geographic(local_crs((0.0, 0.0))) is False


def test_parse_crs_option():
    assert parse_crs_option(" UTM ") == "utm"
    assert parse_crs_option("WGS84") == "wgs84"
    assert parse_crs_option("epsg:4326") == "wgs84" and parse_crs_option("4326") == "wgs84"
    assert parse_crs_option("epsg:32631") == "EPSG:32631"
    assert parse_crs_option("EPSG: 3857") == "EPSG:3857"
    assert parse_crs_option("EPSG:04326") == "EPSG:4326"
    for bad in ("EPSG:x", "EPSG:", "foo:3857", "3857", "EPSG:-1"):
        with pytest.raises(ValueError) as e:
            parse_crs_option(bad)
        assert str(e.value) == f"{bad!r} is not utm, wgs84 or EPSG:<code>"
    with pytest.raises(ValueError) as e:
        parse_crs_option("EPSG:99999999")
    assert str(e.value) == "EPSG:99999999 is not a coordinate reference system PROJ knows"
    with pytest.raises(ValueError) as e:
        parse_crs_option("EPSG:4978")  # geocentric
    assert str(e.value) == "EPSG:4978 is neither a projected nor a geographic 2D frame"
    with pytest.raises(ValueError) as e:
        parse_crs_option("EPSG:5703")  # a vertical datum (heights)
    assert str(e.value) == "EPSG:5703 is neither a projected nor a geographic 2D frame"
    assert parse_crs_option("EPSG:4258") == "EPSG:4258"  # geographic, not WGS84


def test_output_crs():
    assert output_crs(None, "EPSG:32631") == "EPSG:32631"
    assert output_crs("utm", "EPSG:32734") == "EPSG:32734"
    assert output_crs("wgs84", "EPSG:32631") == "EPSG:4326"
    assert output_crs(None, "EPSG:32631", default="wgs84") == "EPSG:4326"
    assert output_crs("", "EPSG:32631", default="EPSG:3857") == "EPSG:3857"
    assert output_crs("EPSG:3857", "EPSG:32631") == "EPSG:3857"
    # a local frame has no EPSG code: the UTM zone of its origin
    assert output_crs("utm", local_crs((50.63, 5.57))) == "EPSG:32631"
    assert output_crs("utm", local_crs((-33.9, 18.4))) == "EPSG:32734"
    # a geographic frame has a code but is not projected: the zone of its (0, 0), lon 0 lat 0
    assert output_crs("utm", "EPSG:4326") == "EPSG:32631"
    assert output_crs("utm", "EPSG:4258") == "EPSG:32631"
    with pytest.raises(ValueError):
        output_crs("mercator", "EPSG:32631")


def test_registered_frame():
    xy = np.array([[1.0, 2.0]])
    code, out = registered_frame("EPSG:32631", xy)
    assert code == 32631 and type(code) is int and out is xy
    crs = local_crs((50.63, 5.57))
    pts = np.array([[0.0, 0.0], [100.0, -50.0]])
    code, out = registered_frame(crs, pts)
    assert code == 32631 and type(code) is int
    want = from_lonlat("EPSG:32631")(to_lonlat(crs)(pts))
    assert np.allclose(out, want, atol=1e-6)
    assert 600_000 < out[0, 0] < 700_000 and 5_600_000 < out[0, 1] < 5_620_000  # Liège in zone 31N
    # metres stay metres (scale within 0.9996..1.0004), the axes turn by the grid convergence, about 2 degrees here
    d = out[1] - out[0]
    assert abs(np.hypot(*d) - np.hypot(100.0, 50.0)) < 0.05
    turn = np.degrees(np.arctan2(d[1], d[0]) - np.arctan2(-50.0, 100.0))
    assert 1.9 < turn < 2.1
    code, out = registered_frame(local_crs((-33.9, 18.4)), np.zeros((1, 2)))
    assert code == 32734 and 6_200_000 < out[0, 1] < 6_300_000


def test_layer_crs():
    assert layer_crs({"crs": "EPSG:32631"}, (0.0, 0.0)) == "EPSG:32631"
    local = local_crs((50.63, 5.57))
    assert layer_crs(None, (50.63, 5.57)) == local
    assert layer_crs({}, (50.63, 5.57)) == local
    assert layer_crs({"crs": ""}, (50.63, 5.57)) == local
    assert layer_crs({"crs": None}, (50.63, 5.57)) == local
