"""Attribute columns to Arrow (sengine.nodes.export.table._array): text in object columns without a Python loop.

The fast path (Arrow converts an object column itself) is taken only when
it gives text or nulls; anything else goes the element-by-element way.  Both must give
the same array as that way always did, whatever the column holds.
"""

from __future__ import annotations

import numpy as np
import pyarrow as pa
from hypothesis import given, settings
from hypothesis import strategies as st

from sengine.nodes.export.table import _array


def _by_element(col: np.ndarray):
    """The element-by-element conversion (the oracle)."""
    values = [v.item() if isinstance(v, np.generic) else v for v in col.tolist()]
    try:
        return pa.array(values)
    except (pa.ArrowInvalid, pa.ArrowTypeError):
        return pa.array([None if v is None else str(v) for v in values], type=pa.string())


VALUES = st.one_of(
    st.none(),
    st.text(max_size=6),
    st.sampled_from(["residential", "Kirchberg an der Iller", "Liège", "", "日本"]).map(np.str_),
    st.integers(-(2**40), 2**40),
    st.floats(allow_nan=False, width=32).map(np.float32),
    st.floats(allow_nan=True),
    st.booleans(),
    st.binary(max_size=3),
)


@settings(max_examples=300, deadline=None)
@given(st.lists(VALUES, max_size=12), st.booleans())
def test_object_columns_convert_as_element_by_element(values, text_only):
    if text_only:
        values = [v if v is None or isinstance(v, str) else str(v) for v in values]
    col = np.empty(len(values), dtype=object)
    col[:] = values
    got, want = _array(pa, col), _by_element(col)
    assert got.type == want.type, (values, got.type, want.type)
    assert got.equals(want), values


def test_a_column_of_nothing_but_none_is_null():
    for n in (0, 1, 66_361):
        col = np.full(n, None, dtype=object)
        arr = _array(pa, col)
        assert pa.types.is_null(arr.type) and len(arr) == n and arr.equals(_by_element(col))


def test_a_text_column_of_a_real_size_is_text_with_its_nulls():
    col = np.array(["terrace", None, "detached", np.str_("block")] * 50_000, dtype=object)
    arr = _array(pa, col)
    assert arr.type == pa.string() and arr.null_count == 50_000 and len(arr) == 200_000
    assert arr.slice(0, 4).to_pylist() == ["terrace", None, "detached", "block"]
