"""Benchmark: the viewer page (``--format html``) in headless Chromium: load time and frame rate while orbiting.

For each output folder given (made with ``--format html``), the page is
opened from ``file://`` in Debian's Chromium (headless, ``--disable-gpu``:
WebGL on the CPU through SwiftShader, the only GL this machine has) at
1280 x 800, and the bench records:

* ``load_seconds``: from ``goto`` to the viewer's first frame drawn, and
  ``load_ms`` where it goes: ``scripts`` (reading and parsing ``city.view.js``
  and ``viewer.js``), ``decode`` (the base64 into arrays), ``build`` (meshes
  and tiles), ``colour`` (the first colouring), ``first_frame``;
* ``fps_orbit``: frames drawn per second while the camera circles the
  whole city (``window.sengineViewer.measureFps``: one render per
  ``requestAnimationFrame``, every frame drawn), and ``fps_street``: the
  same from 300 m above the city's centre;
* ``pick_ms``: one click's pick (the GPU pass) and selection;
* the triangles drawn and the size of ``city.view.js``.

A software rasteriser on two shared cores is a floor, not what a laptop's
GPU gives.  Writes ``bench/results/viewer.json``.

    python bench/viewer.py OUT [OUT ...] [--seconds 8]
    # whole Liège: sengine osm ../shared/data/liege_streets.osm.pbf -o /tmp/liege --format glb,geojson,png,html
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

from _browser import browser  # noqa: E402
from _results import RESULTS, write  # noqa: E402


def measure(out: Path, seconds: float) -> dict:
    with browser(viewport=(1280, 800)) as ctx:
        page = ctx.new_page()
        t = time.perf_counter()
        page.goto((out / "index.html").resolve().as_uri(), wait_until="commit", timeout=600_000)
        page.wait_for_function("document.body.dataset.ready", timeout=600_000)
        load = time.perf_counter() - t
        if page.evaluate("document.body.dataset.ready") != "1":
            raise SystemExit(f"{out}: the viewer did not start: {page.inner_text('#error')}")
        tris = page.evaluate("window.sengineViewer.triangles")
        timings = page.evaluate("window.sengineViewer.timings")
        orbit = page.evaluate("(s) => window.sengineViewer.measureFps(s)", seconds)
        t = time.perf_counter()
        page.mouse.click(640, 400)
        pick = time.perf_counter() - t
        page.evaluate(  # 300 m above the first building (ids need not start at 0)
            """() => { const s = window.sengineViewer;
                       const b = s.view.layers.find((l) => l.name === "buildings");
                       return s.focus("buildings", b.columns.id.get(0), 300); }"""
        )
        street = page.evaluate("(s) => window.sengineViewer.measureFps(s)", seconds)
    return {
        "folder": str(out),
        "view_js_mb": round((out / "city.view.js").stat().st_size / 1e6, 1),
        "triangles": tris,
        "load_seconds": round(load, 2),
        "load_ms": timings,
        "fps_orbit": round(orbit["fps"], 2),
        "frames_orbit": orbit["frames"],
        "fps_street": round(street["fps"], 2),
        "pick_ms": round(pick * 1000, 1),
    }


def screenshot(out: Path, path: Path, colour: str = "height", distance: float = 900.0) -> None:
    """The page's 3D view on the city's tallest building, clicked, as a small palette PNG (for docs/)."""
    import io

    from PIL import Image

    with browser(viewport=(1200, 820)) as ctx:
        page = ctx.new_page()
        page.goto((out / "index.html").resolve().as_uri(), wait_until="commit", timeout=600_000)
        page.wait_for_function("document.body.dataset.ready", timeout=600_000)
        page.select_option("#colour", colour)
        if "buildings" in page.evaluate("window.sengineViewer.layers"):  # click the tallest building
            at = page.evaluate(
                """(d) => { const s = window.sengineViewer;
                           const b = s.view.layers.find((l) => l.name === "buildings");
                           let best = 0;
                           for (let i = 1; i < b.features; i++)
                             if (b.columns.height.get(i) > b.columns.height.get(best)) best = i;
                           return s.focus("buildings", b.columns.id.get(best), d, 35); }""",
                distance,
            )
            if at:
                page.mouse.click(at["x"], at["y"])
        page.wait_for_timeout(300)
        png = page.locator("#stage").screenshot()
    image = Image.open(io.BytesIO(png)).convert("RGB").quantize(colors=256, method=Image.Quantize.FASTOCTREE)
    path.parent.mkdir(parents=True, exist_ok=True)
    image.save(path, optimize=True)
    print(f"wrote {path} ({path.stat().st_size / 1e3:.0f} kB)", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", nargs="+", type=Path)
    ap.add_argument("--seconds", type=float, default=8.0)
    ap.add_argument("--screenshots", type=Path, help="also write DIR/viewer-<folder name>.png of each page")
    args = ap.parse_args()
    if args.screenshots:
        for out in args.folders:
            screenshot(out, args.screenshots / f"viewer-{out.name}.png")
        return
    rows = []
    for out in args.folders:
        row = measure(out, args.seconds)
        print(row, flush=True)
        rows.append(row)
    write(RESULTS / "viewer.json", "viewer", {"seconds_each": args.seconds, "viewport": [1280, 800], "cities": rows})


if __name__ == "__main__":
    main()
