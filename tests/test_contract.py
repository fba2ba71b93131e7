"""The contract every registered node keeps (style.md: one contract test for all nodes).

On empty input a node returns a Layer for every declared output port, or
raises a one-line SEngineError (a source node whose plan lacks its map);
never another exception.  Outputs are valid geometries and inputs are left
untouched.
"""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from sengine import CityPlan, Context, Layer
from sengine.errors import SEngineError
from sengine.registry import check_kind, get, kinds, names

_DTYPES = {"iu": np.int64, "f": float, "b": bool, "UO": "U16"}


def empty(kind: str) -> Layer:
    """An empty layer with the required columns its kind declares (sengine/nodes/kinds.py)."""
    cols = kinds().get(kind, {})
    return Layer.empty(**{c: _DTYPES[d] for c, (d, required, _) in cols.items() if required})


@pytest.mark.parametrize("name", names())
def test_node_on_empty_input(name, tmp_path):
    cls = get(name)
    ctx = Context(seed=1, plan=CityPlan(size=(500.0, 400.0)), base_dir=tmp_path, out=tmp_path, formats=frozenset())
    inputs = {port: empty(decl.kind) for port, decl in cls.inputs.items()}
    before = {port: (len(layer), dict(layer.attrs)) for port, layer in inputs.items()}
    try:
        node = cls("n", {}, ctx)  # a source node needs its file: a one-line error
        outputs = node.run(**inputs)
    except SEngineError as err:
        assert "\n" not in str(err)
        return
    assert set(outputs) == set(cls.outputs), f"{name} returned {sorted(outputs)}"
    for port, layer in outputs.items():
        assert isinstance(layer, Layer)
        check_kind(layer, cls.outputs[port].kind, where=f"{name}.{port}")
        if len(layer):
            assert shapely.is_valid(layer.geometry).all(), f"{name}.{port} has invalid geometry"
    for port, layer in inputs.items():
        assert (len(layer), dict(layer.attrs)) == before[port]


@pytest.mark.parametrize("name", names())
def test_node_declaration_is_complete(name):
    d = get(name).describe()
    assert d["doc"], f"{name} has no docstring"
    for p in d["params"]:
        assert p["doc"], f"{name}.{p['name']} has no doc line"
        if p["type"] in ("float", "int"):
            assert p["unit"], f"{name}.{p['name']} has no unit"
