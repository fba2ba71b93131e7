"""Issue 13: what a run imports (start-up time), and the numpy stand-ins for scipy on the demo's path."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
from conftest import ROOT
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from sengine.nodes.roads.patterns import BRUTE_FORCE_SITES, nearest_site

coords = arrays(np.float64, st.tuples(st.integers(1, 60), st.just(2)), elements=st.floats(-1e4, 1e4, width=32))


@settings(max_examples=150, deadline=None)
@given(coords, coords)
def test_nearest_site_is_the_kd_trees(points, sites):
    from scipy.spatial import cKDTree

    got = nearest_site(points, sites)
    dist, want = cKDTree(sites).query(points)
    assert got.shape == (len(points),) and got.min() >= 0 and got.max() < len(sites)
    # the same site, or one exactly as far (a tie)
    mine = np.hypot(*(points - sites[got]).T)
    assert np.allclose(mine, dist, rtol=0, atol=1e-9)
    unique = np.unique(sites, axis=0).shape[0] == len(sites)
    if unique:
        d2 = ((points[:, None, :] - sites[None, :, :]) ** 2).sum(-1)
        ties = (np.sort(d2, axis=1)[:, :2] if len(sites) > 1 else d2)[:, 0] == (
            np.sort(d2, axis=1)[:, 1] if len(sites) > 1 else -1
        )
        assert np.array_equal(got[~ties], want[~ties])


def test_nearest_site_many_sites_and_chunks():
    rng = np.random.default_rng(3)
    sites = rng.uniform(0, 1000, (BRUTE_FORCE_SITES + 1, 2))  # the k-d tree's side
    pts = rng.uniform(0, 1000, (5000, 2))
    a = nearest_site(pts, sites)
    b = nearest_site(pts, sites[:BRUTE_FORCE_SITES])  # numpy's side, several chunks of 16384 points
    full = ((pts[:, None, :] - sites[None]) ** 2).sum(-1)
    assert np.array_equal(a, full.argmin(1))
    assert np.array_equal(b, full[:, :BRUTE_FORCE_SITES].argmin(1))
    big = rng.uniform(0, 1000, (40_000, 2))  # more than one chunk of (1 << 22) // 200 points
    assert np.array_equal(nearest_site(big, sites[:200]), nearest_site(big[::-1], sites[:200])[::-1])


def test_manhattan_run_imports_what_it_uses(tmp_path):
    """The demo's run imports no scipy, no OSM reader, no GeoPackage/Parquet writer, no web server."""
    code = (
        "import sys, json\n"
        "from sengine.cli import main\n"
        f"rc = main(['run', 'configs/manhattan.xml', '-o', {str(tmp_path / 'out')!r}, '--quiet', '--workers', '1'])\n"
        "assert rc == 0, rc\n"
        "print(json.dumps(sorted(sys.modules)))\n"
    )
    res = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        cwd=ROOT,
        env=dict(os.environ, PYTHONPATH=str(ROOT)),
        timeout=600,
    )
    assert res.returncode == 0, res.stderr
    mods = set(json.loads(res.stdout.strip().splitlines()[-1]))
    assert (tmp_path / "out" / "city.glb").stat().st_size > 1e6
    heavy = {m.split(".")[0] for m in mods} & {
        "scipy",
        "skimage",
        "trimesh",
        "networkx",
        "osmium",
        "pyogrio",
        "pyarrow",
    }
    assert not heavy, heavy
    for m in ("sengine.nodes.osm.read", "sengine.nodes.export.gpkg", "sengine.nodes.export.parquet", "http.server"):
        assert m not in mods, m
