"""rerun component columns built in bulk from arrow arrays, where rerun's Python API would
build them one row at a time (:func:`~analysis.recording.columns.bar_chart_column`), and the
action probabilities as five named bars (:func:`action_bar_columns`)."""

from __future__ import annotations

import numpy as np
import pyarrow as pa
import rerun as rr


class _ArrowBatch:
    """A ready arrow array as a rerun component batch (what ``rr.ComponentColumn`` takes)."""

    def __init__(self, array: pa.Array, descriptor):
        self._array, self._descriptor = array, descriptor

    def as_arrow_array(self) -> pa.Array:
        return self._array

    def component_descriptor(self):
        return self._descriptor


def bar_chart_column(values: np.ndarray) -> rr.ComponentColumn:
    """``BarChart`` values as one column of ``n`` bar charts (rows of ``values [n, k]``, float64).

    rerun's Python API builds a bar chart's tensor one call at a time (about 1 ms each); this
    builds the same arrow layout (TensorData: shape ``[k]``, no names, an F64 buffer) for all
    rows at once, typed after a one-row sample.
    """
    values = np.ascontiguousarray(values, dtype=np.float64)
    n, k = values.shape
    sample = next(iter(rr.BarChart.columns(values=np.zeros(max(k, 1)))))
    st = sample.component_batch.as_arrow_array().type
    ut = st.field("buffer").type
    names = [f.name for f in ut]
    children = [pa.ListArray.from_arrays(pa.array(np.arange(0, n * k + 1, k, dtype=np.int32)), pa.array(values.reshape(-1)),
                                         type=f.type) if f.name == "F64" else pa.array([], type=f.type) for f in ut]
    buf = pa.UnionArray.from_dense(pa.array(np.full(n, ut.type_codes[names.index("F64")], dtype=np.int8)),
                                   pa.array(np.arange(n, dtype=np.int32)), children, field_names=names,
                                   type_codes=list(ut.type_codes)).view(ut)
    shape = pa.ListArray.from_arrays(pa.array(np.arange(n + 1, dtype=np.int32)), pa.array(np.full(n, k, dtype=np.uint64)),
                                     type=st.field("shape").type)
    arr = pa.StructArray.from_arrays([shape, pa.nulls(n, st.field("names").type), buf], fields=list(st))
    desc = sample.component_descriptor()
    return rr.ComponentColumn(desc, _ArrowBatch(arr, desc))


#: RGBA of the five action bars (hard braking red .. hard acceleration green).
ACTION_RGBA = np.array([[200, 40, 40, 255], [235, 140, 60, 255], [170, 170, 170, 255], [120, 190, 90, 255],
                        [40, 150, 60, 255]], dtype=np.uint8)
#: Half width of an action bar (bars at x = 0..4).
BAR_HALF_WIDTH = 0.35


def action_bar_columns(probs: np.ndarray) -> list:
    """``Boxes2D`` columns of ``n`` decisions' action probabilities ``probs [n, 5]`` as bars:
    bar ``i`` at x = i, from y = 0 up to y = -p (the 2D view draws y downwards), labelled with
    ``p`` to two decimals."""
    probs = np.asarray(probs, dtype=np.float64)
    n, k = probs.shape
    centers = np.stack([np.tile(np.arange(k, dtype=np.float64), n), -0.5 * probs.reshape(-1)], axis=1)
    half = np.stack([np.full(n * k, BAR_HALF_WIDTH), 0.5 * probs.reshape(-1)], axis=1)
    labels = pa.array([f"{v:.2f}" for v in probs.reshape(-1)], type=pa.string())
    colors = np.tile(ACTION_RGBA.astype(np.uint32) @ np.array([1 << 24, 1 << 16, 1 << 8, 1], dtype=np.uint32), n)
    return [*rr.Boxes2D.columns(centers=centers.astype(np.float32), half_sizes=half.astype(np.float32),
                                labels=labels, colors=colors.astype(np.uint32)).partition(np.full(n, k)),
            *rr.Boxes2D.columns(show_labels=[True] * n)]
