"""Draw ``roadmap.png``: a road-map image for ``configs/roadmap.xml`` (white roads on black).

A 600 x 400 px picture of a 3,000 x 2,000 m town (5 m per pixel): a grid
district to the east, an old town of curved streets to the west, a ring
road and a diagonal avenue between them.  Run it to regenerate the image;
the output is deterministic.

Usage::

    python configs/maps/make_roadmap.py [OUT.png]
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

from PIL import Image, ImageDraw

W, H, ROAD = 600, 400, 3  # pixels; road stroke width in pixels


def draw(path: Path) -> None:
    im = Image.new("1", (W, H), 0)
    d = ImageDraw.Draw(im)

    def line(points, width=ROAD):
        d.line(points, fill=1, width=width, joint="curve")

    # grid district (east), streets every 40 px, avenues every 120 px
    for x in range(330, 581, 40):
        line([(x, 30), (x, 370)], ROAD + (2 if (x - 330) % 120 == 0 else 0))
    for y in range(30, 371, 40):
        line([(330, y), (580, y)], ROAD + (2 if (y - 30) % 120 == 0 else 0))
    # ring road around the old town (west)
    cx, cy, r = 170, 200, 150
    ring = [(cx + r * math.cos(t / 90 * math.pi), cy + r * math.sin(t / 90 * math.pi)) for t in range(181)]
    line(ring, ROAD + 2)
    # old town: radial streets and two curved rings
    for k in range(8):
        a = k * math.pi / 4 + 0.2
        line([(cx + 20 * math.cos(a), cy + 20 * math.sin(a)), (cx + r * math.cos(a), cy + r * math.sin(a))])
    for rr in (55, 100):
        pts = [(cx + rr * math.cos(t / 60 * math.pi), cy + rr * math.sin(t / 60 * math.pi) * 0.95) for t in range(121)]
        line(pts)
    line([(cx + 20 * math.cos(t / 30 * math.pi), cy + 20 * math.sin(t / 30 * math.pi)) for t in range(61)])
    # avenue from the old town to the grid, and one diagonal across the grid
    line([(cx + r, cy), (330, 190)], ROAD + 2)
    line([(330, 370), (580, 30)], ROAD + 1)
    im.save(path, optimize=True)


if __name__ == "__main__":
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).with_name("roadmap.png")
    draw(out)
    print(out)
