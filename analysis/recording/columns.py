"""rerun component columns built in bulk from arrow arrays, where rerun's Python API would
build them one row at a time (:func:`~analysis.recording.columns.bar_chart_column`)."""

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
