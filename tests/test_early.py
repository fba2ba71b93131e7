"""Early jobs: a node's work that needs only some inputs, started in another process (issue 13).

``SENode.early`` hands the engine a job once the layers of ``early_inputs``
are made; with workers the job runs in a forked process
(:class:`sengine.parallel.Background`) while the nodes in between run here,
and the node takes its result with ``early_result``.  ``export.city`` makes
the buildings' roofs that way; the files must be the same bytes as a run
with one worker, which starts no early job.
"""

from __future__ import annotations

import os
import time
from functools import partial

import numpy as np
import pytest
import shapely
from conftest import ROOT

import sengine
from sengine import Layer, Port, SENode, register
from sengine.errors import InputDataError
from sengine.network import Network
from sengine.nodes.export import roofs
from sengine.nodes.export.city import early_solids
from sengine.nodes.export.prepare import prepare_layers
from sengine.parallel import Background, can_fork

pytestmark = pytest.mark.skipif(not can_fork(), reason="forking is not safe on this system")


def _area_and_pid(layer: Layer) -> tuple[float, int]:
    return float(shapely.area(layer.geometry).sum()), os.getpid()


def _fails() -> None:
    raise InputDataError("bad file", where="x.osm")


def test_a_background_job_runs_in_another_process_and_hands_back_its_result():
    layer = Layer.from_geoms([shapely.box(0, 0, i + 1, 2) for i in range(50)])
    job = Background(partial(_area_and_pid, layer))
    area, pid = job.result()
    assert pid != os.getpid()
    assert area == pytest.approx(2 * sum(range(1, 51)))


def test_a_background_job_raises_its_own_error_here():
    job = Background(_fails)
    with pytest.raises(InputDataError, match="x.osm: bad file"):
        job.result()


def test_a_background_job_nobody_waits_for_is_stopped_at_once():
    job = Background(partial(time.sleep, 60))
    t = time.monotonic()
    job.close()
    assert time.monotonic() - t < 10  # not the 60 s of the job


def test_startable_only_with_workers():
    assert not Background.startable(1)
    assert Background.startable(2)


# -- the engine ------------------------------------------------------------------------------


@register
class _Squares(SENode):
    """Squares of 1..count m."""

    name = "test_early.squares"
    outputs = {"squares": Port("polygons")}

    def run(self):
        return {"squares": Layer.from_geoms([shapely.box(0, 0, s, s) for s in range(1, 41)])}


@register
class _Slow(SENode):
    """A node in between: the early job runs meanwhile."""

    name = "test_early.slow"
    inputs = {"input": Port("polygons")}
    outputs = {"output": Port("polygons")}

    def run(self, *, input):
        time.sleep(0.2)
        return {"output": input}


@register
class _Sum(SENode):
    """Reports the squares' area: from its early job when one ran, else computed here."""

    name = "test_early.sum"
    inputs = {"squares": Port("polygons"), "later": Port("polygons")}
    outputs = {}
    early_inputs = ("squares",)

    def early(self, *, squares=None):
        return partial(_area_and_pid, squares)

    def run(self, *, squares, later):
        made = self.early_result()
        area, pid = made if made is not None else _area_and_pid(squares)
        return sengine.NodeResult({}, {"area": area, "elsewhere": pid != os.getpid()})


def _network() -> Network:
    net = Network()
    net.add("squares", "test_early.squares")
    net.add("slow", "test_early.slow")
    net.add("sum", "test_early.sum")
    net.connect("squares.squares", "slow.input")
    net.connect("squares.squares", "sum.squares")
    net.connect("slow.output", "sum.later")
    return net


def test_the_engine_starts_the_early_job_with_workers_only():
    expected = float(sum(s * s for s in range(1, 41)))
    one = _network().run(seed=1, workers=1).stats["report"]["sum"]
    two = _network().run(seed=1, workers=2).stats["report"]["sum"]
    assert one == {"area": expected, "elsewhere": False}
    assert two == {"area": expected, "elsewhere": True}


# -- the export's roofs ---------------------------------------------------------------------


def _buildings(n: int = 40) -> Layer:
    rng = np.random.default_rng(3)
    geoms = []
    for i in range(n):
        x, y = 40.0 * (i % 8), 40.0 * (i // 8)
        outer = shapely.box(x, y, x + 20 + rng.uniform(0, 8), y + 15 + rng.uniform(0, 8))
        if i % 3 == 0:  # an L: concave, to the straight skeleton
            outer = outer.difference(shapely.box(x + 10, y + 8, x + 40, y + 40))
        if i % 5 == 0:  # a courtyard: a hole, to CGAL's extrusion
            outer = shapely.box(x, y, x + 30, y + 30).difference(shapely.box(x + 8, y + 8, x + 22, y + 22))
        geoms.append(outer)
    kinds = np.array(["hip", "gable", "flat", "parapet"], dtype=object)[np.arange(n) % 4]
    return Layer.from_geoms(geoms, height=rng.uniform(8, 40, n), roof=kinds)


def test_early_solids_are_the_exports_own():
    b = _buildings()
    key, made = early_solids(b, 2)
    prepared = prepare_layers({"buildings": b}, None)[0]["buildings"]
    here = roofs.layer_solids(prepared, 2)
    assert key == roofs.solids_key(prepared, 2)
    assert len(here.faces) > 40 * 6
    for name in ("vertices", "faces", "vertex_feature", "face_kind"):
        assert np.array_equal(getattr(made, name), getattr(here, name))


def test_solids_of_other_buildings_are_not_taken():
    b = _buildings()
    prepared = prepare_layers({"buildings": b}, None)[0]["buildings"]
    key, made = early_solids(b, 2)
    taller = prepared.with_columns(height=np.asarray(prepared["height"]) + 1.0)
    assert roofs.solids_key(taller, 2) != key
    assert roofs.solids_key(prepared, 1) != key
    with roofs.shared_solids(taller, 2, made=(key, made)) as solids:
        assert solids is not made
        assert solids.vertices[:, 2].max() == pytest.approx(made.vertices[:, 2].max() + 1.0)
    with roofs.shared_solids(prepared, 2, made=(key, made)) as solids:
        assert solids is made


@pytest.mark.slow
def test_manhattan_roofs_made_early_write_the_same_files(tmp_path, monkeypatch):
    calls = []
    made_here = roofs.building_solids

    def counted(*args, **kwargs):
        calls.append(os.getpid())  # this process's list: the early job's process has its own copy
        return made_here(*args, **kwargs)

    monkeypatch.setattr(roofs, "building_solids", counted)
    net = sengine.load(ROOT / "configs" / "manhattan.xml")
    net.run(out=tmp_path / "one", formats={"glb", "html"}, workers=1)
    assert calls == [os.getpid()]
    calls.clear()
    net.run(out=tmp_path / "two", formats={"glb", "html"}, workers=2)
    assert calls == []  # made by the early job, not here
    for name in ("city.glb", "city.view.js", "index.html"):
        one, two = ((tmp_path / d / name).read_bytes() for d in ("one", "two"))
        assert len(one) > 1000 and one == two, name
