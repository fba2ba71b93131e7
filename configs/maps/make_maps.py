"""Draw the demo configs' image maps, deterministically, with Pillow.

    python configs/maps/make_maps.py          # rewrites the PNGs beside this file

Each city's shapes are written in metres on its extent (x east, y north, as
in the configs) and rasterized without anti-aliasing into palette PNGs, so a
map holds exactly the colours of its config's ``<district>`` and
``<landuse>`` rules.  Height maps are small 8-bit greyscale images (the
engine samples them bilinearly).

* ``manhattan_*`` (configs/manhattan.xml, 7200 x 10800 m): a long island on
  the bearing of Manhattan's grid (29 deg east of north) in water, a
  Central-Park-like rectangle, four districts along the island, a skyline
  with a downtown and a midtown peak.
* ``paris_*`` (configs/paris.xml, 4500 x 3000 m): a river crossing the city,
  a radial star in the west, organic quarters around, one square park.
* ``districts_*`` (configs/districts.xml, 3000 x 2000 m): a grid, a radial
  and an organic district meeting along curved borders, with a lake.
* ``metropolis_*`` (configs/metropolis.xml, drawn on 32 x 32 km, placed on 27 x 27 km; ``--scale`` stretches
  it): a downtown grid on a river bend, a radial district and an old town
  beside it, residential grids on three bearings, suburbs of small recursive
  lots, two lakes and a ring of parks.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

HERE = Path(__file__).resolve().parent

WATER = (32, 96, 255)
LAND = (255, 255, 255)
PARK = (48, 160, 64)


def hexrgb(text: str) -> tuple[int, int, int]:
    text = text.lstrip("#")
    return int(text[0:2], 16), int(text[2:4], 16), int(text[4:6], 16)


class Canvas:
    """A palette image drawn in city metres."""

    def __init__(self, size_m, size_px, background):
        self.w, self.h = size_m
        self.cols, self.rows = size_px
        self.im = Image.new("RGB", size_px, background)
        self.draw = ImageDraw.Draw(self.im)

    def px(self, pts):
        return [(x / self.w * self.cols, (self.h - y) / self.h * self.rows) for x, y in pts]

    def polygon(self, pts, colour):
        self.draw.polygon(self.px(pts), fill=colour)

    def save(self, name):
        # adaptive palette of the few exact colours: small files, exact pixels
        pal = self.im.quantize(colors=16, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
        pal.save(HERE / name, optimize=True)


def rotate(pts, angle_deg, origin):
    t = math.radians(angle_deg)
    c, s = math.cos(t), math.sin(t)
    ox, oy = origin
    return [(ox + u * c - v * s, oy + u * s + v * c) for u, v in pts]


def height_png(name, size_m, size_px, peaks, base=0.08):
    """Greyscale: ``base`` plus Gaussian peaks ``(x, y, sigma, amplitude)`` (m)."""
    w, h = size_m
    cols, rows = size_px
    x = (np.arange(cols) + 0.5) / cols * w
    y = h - (np.arange(rows) + 0.5) / rows * h
    xx, yy = np.meshgrid(x, y)
    g = np.full(xx.shape, base)
    for px_, py_, sig, amp in peaks:
        g += amp * np.exp(-((xx - px_) ** 2 + (yy - py_) ** 2) / (2 * sig**2))
    g = np.clip(np.rint(g * 255), 0, 255).astype(np.uint8)
    Image.fromarray(g, mode="L").save(HERE / name, optimize=True)


# -- Manhattan-like ------------------------------------------------------------------
MANHATTAN = {
    "size": (7200.0, 10800.0),
    "px": (400, 600),
    # island frame: u along bearing 29 deg east of north, v across (m)
    "origin": (1270.0, 1040.0),
    "bearing": 29.0,
    "districts": {  # colour -> (u from, u to)
        "#d9a441": (-1e5, 1900.0),  # downtown: organic
        "#8fbf5a": (1900.0, 3300.0),  # village: its own grid
        "#d03030": (3300.0, 6900.0),  # midtown
        "#6a5acd": (6900.0, 1e5),  # uptown
    },
}


def manhattan_island():
    """Outline in the island frame: a pointed south tip, widest in the middle."""
    right = [
        (0, 300),
        (600, 900),
        (1500, 1150),
        (3000, 1250),
        (5000, 1200),
        (7000, 1150),
        (8600, 1000),
        (9400, 700),
        (9800, 200),
    ]
    left = [
        (9700, -300),
        (9200, -800),
        (8000, -1050),
        (6000, -1100),
        (4000, -1150),
        (2000, -1100),
        (900, -800),
        (200, -250),
    ]
    return right + left


def make_manhattan():
    m = MANHATTAN
    ang = 90.0 - m["bearing"]  # the u axis, counter-clockwise from east
    island = rotate(manhattan_island(), ang, m["origin"])
    land = Canvas(m["size"], m["px"], WATER)
    land.polygon(island, LAND)
    park = [(5200, -270), (7200, -270), (7200, 270), (5200, 270)]  # aligned with the grid
    land.polygon(rotate(park, ang, m["origin"]), PARK)
    land.save("manhattan_landuse.png")

    dist = Canvas(m["size"], m["px"], hexrgb("#6a5acd"))
    for colour, (u0, u1) in m["districts"].items():
        band = [(u0, -2e4), (u1, -2e4), (u1, 2e4), (u0, 2e4)]
        dist.polygon(rotate(band, ang, m["origin"]), hexrgb(colour))
    dist.save("manhattan_districts.png")

    def at(u, v):
        return rotate([(u, v)], ang, m["origin"])[0]

    peaks = [(*at(700, 0), 700.0, 0.9), (*at(4600, 0), 900.0, 0.85), (*at(8200, 0), 1200.0, 0.25)]
    height_png("manhattan_height.png", m["size"], (60, 90), peaks)


# -- Paris-like ----------------------------------------------------------------------
def river(points, width):
    """A band of ``width`` (m) along a polyline, as a polygon."""
    pts = np.asarray(points, float)
    left, right = [], []
    for i, p in enumerate(pts):
        a = pts[max(i - 1, 0)]
        b = pts[min(i + 1, len(pts) - 1)]
        d = (b - a) / np.hypot(*(b - a))
        n = np.array([-d[1], d[0]]) * width / 2
        left.append(tuple(p + n))
        right.append(tuple(p - n))
    return left + right[::-1]


def make_paris():
    k = 0.75  # shapes drawn for a 6 x 4 km city, placed on 4.5 x 3 km

    def sc(pts):
        return [(x * k, y * k) for x, y in pts]

    size, px = (4500.0, 3000.0), (450, 300)
    seine = [
        (-100, 2300),
        (900, 2500),
        (1900, 2250),
        (2800, 1900),
        (3700, 1950),
        (4600, 2300),
        (5400, 2150),
        (6100, 1800),
    ]
    land = Canvas(size, px, LAND)
    land.polygon(sc(river(seine, 170.0)), WATER)
    land.polygon(sc([(3900, 1250), (4500, 1250), (4500, 1700), (3900, 1700)]), PARK)
    land.save("paris_landuse.png")
    dist = Canvas(size, px, hexrgb("#c8a060"))  # organic outskirts
    star = [(1600 + 1300 * math.cos(t), 2000 + 1300 * math.sin(t)) for t in np.linspace(0, 2 * math.pi, 40)]
    dist.polygon(sc(star), hexrgb("#5080c0"))  # radial star (l'Etoile), centre (1200, 1500)
    centre = [(3300, 1100), (4800, 900), (5300, 2000), (4900, 3000), (3400, 3100), (3000, 2200)]
    dist.polygon(sc(centre), hexrgb("#a04060"))  # organic centre, denser
    dist.save("paris_districts.png")
    height_png("paris_height.png", size, (60, 40), [(2900, 1600, 700.0, 0.35), (1200, 1500, 500.0, 0.3)], base=0.25)


# -- three districts ---------------------------------------------------------------------
def make_districts():
    size, px = (3000.0, 2000.0), (450, 300)
    dist = Canvas(size, px, hexrgb("#d03030"))  # grid (west and south)
    radial = [(1800 + 700 * math.cos(t), 1300 + 650 * math.sin(t)) for t in np.linspace(0, 2 * math.pi, 48)]
    organic = [(2000, -10), (3010, -10), (3010, 2010), (2600, 2010), (2500, 1200), (2200, 600)]
    dist.polygon(organic, hexrgb("#30a030"))
    dist.polygon(radial, hexrgb("#3050d0"))
    dist.save("districts_districts.png")
    land = Canvas(size, px, LAND)
    lake = [(600 + 220 * math.cos(t), 500 + 150 * math.sin(t)) for t in np.linspace(0, 2 * math.pi, 32)]
    land.polygon(lake, WATER)
    land.save("districts_landuse.png")


# -- a metropolis of about a million lots ---------------------------------------------
METROPOLIS = (32000.0, 32000.0)


def make_metropolis():
    size, px = METROPOLIS, (640, 640)
    w, h = size
    dist = Canvas(size, px, hexrgb("#b0b0b0"))  # suburbs: small recursive lots
    ring = [(w / 2 + 12500 * math.cos(t), h / 2 + 11500 * math.sin(t)) for t in np.linspace(0, 2 * math.pi, 64)]
    dist.polygon(ring, hexrgb("#6a5acd"))  # inner residential, on the city's bearing
    inner_w = [p for p in ring if p[0] < w / 2 - 2000]
    dist.polygon(
        sorted(inner_w, key=lambda p: p[1]) + [(w / 2 - 2000, h / 2 + 11000), (w / 2 - 2000, h / 2 - 11000)],
        hexrgb("#8fbf5a"),
    )  # western residential, on another bearing
    core = [(w / 2 + 6000 * math.cos(t), h / 2 + 5000 * math.sin(t)) for t in np.linspace(0, 2 * math.pi, 48)]
    dist.polygon(core, hexrgb("#d03030"))  # downtown grid
    star = [
        (w / 2 - 7500 + 2600 * math.cos(t), h / 2 + 5500 + 2600 * math.sin(t)) for t in np.linspace(0, 2 * math.pi, 40)
    ]
    dist.polygon(star, hexrgb("#5080c0"))  # radial
    old = [
        (w / 2 + 7000 + 2400 * math.cos(t), h / 2 - 6000 + 2000 * math.sin(t)) for t in np.linspace(0, 2 * math.pi, 40)
    ]
    dist.polygon(old, hexrgb("#c8a060"))  # organic old town
    dist.save("metropolis_districts.png")
    land = Canvas(size, px, LAND)
    flow = [
        (-200, 0.62 * h),
        (0.2 * w, 0.58 * h),
        (0.4 * w, 0.47 * h),
        (0.55 * w, 0.44 * h),
        (0.7 * w, 0.36 * h),
        (0.85 * w, 0.3 * h),
        (w + 200, 0.22 * h),
    ]
    land.polygon(river(flow, 260.0), WATER)
    for cx, cy, rx, ry in ((0.2 * w, 0.2 * h, 1400, 900), (0.78 * w, 0.8 * h, 1100, 1500)):
        land.polygon([(cx + rx * math.cos(t), cy + ry * math.sin(t)) for t in np.linspace(0, 2 * math.pi, 40)], WATER)
    for t in np.linspace(0, 2 * math.pi, 9)[:-1]:  # a ring of parks between downtown and the residential grids
        cx, cy = w / 2 + 8000 * math.cos(t), h / 2 + 7600 * math.sin(t)
        land.polygon([(cx - 500, cy - 350), (cx + 500, cy - 350), (cx + 500, cy + 350), (cx - 500, cy + 350)], PARK)
    land.save("metropolis_landuse.png")
    peaks = [
        (w / 2, h / 2, 2500.0, 0.9),
        (w / 2 - 7500, h / 2 + 5500, 1800.0, 0.4),
        (w / 2 + 7000, h / 2 - 6000, 2000.0, 0.3),
    ]
    height_png("metropolis_height.png", size, (128, 128), peaks, base=0.04)


if __name__ == "__main__":
    make_manhattan()
    make_paris()
    make_districts()
    make_metropolis()
    for f in sorted(HERE.glob("*.png")):
        print(f"{f.name}: {f.stat().st_size} bytes")
