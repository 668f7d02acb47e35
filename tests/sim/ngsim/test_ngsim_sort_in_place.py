"""NGSIM files whose rows are not in (vehicle, frame) order read as the sorted file does: rows
interleaved by frame (sorted in place after reading) and rows in random order (sorted in place,
validated chunk by chunk, the table built over the same memory)."""

import numpy as np
import pandas as pd
from ngsim_testdata import synthetic_table

from sim.ngsim.assemble import table_in_place
from sim.ngsim.format import NGSIM_COLUMNS
from sim.ngsim.io import read_ngsim
from sim.ngsim.write import write_ngsim_csv, write_ngsim_csv_blocks
from sim.runtime.schema import COLUMNS


def test_rows_by_frame_and_in_random_order_read_as_the_sorted_file(tmp_path):
    table = synthetic_table(n_vehicles=30, n_frames=40)
    sorted_load = read_ngsim(write_ngsim_csv(table, tmp_path / "sorted.csv", precision="exact"))
    by_frame = table.sort_values(["Frame_ID", "Vehicle_ID"], kind="stable")
    shuffled = table.sample(frac=1.0, random_state=0)
    for name, rows in (("by_frame.csv", by_frame), ("shuffled.csv", shuffled)):
        path = write_ngsim_csv_blocks([rows], tmp_path / name, precision="exact")
        load = read_ngsim(path, chunksize=97)  # many chunks: the chunked validation of the sorted rows
        pd.testing.assert_frame_equal(load.table, sorted_load.table)
        assert list(load.table.dtypes.astype(str)) == list(COLUMNS.values())
        assert load.report.rows_kept == len(table) and load.report.vehicles == 30


def test_table_in_place_is_the_table_over_the_same_memory():
    table = synthetic_table(n_vehicles=3, n_frames=5)
    data = np.ascontiguousarray(table[list(NGSIM_COLUMNS)].to_numpy(dtype=np.float64).T)
    out = table_in_place(data)
    pd.testing.assert_frame_equal(out, table)
    for c in ("Local_Y", "Vehicle_ID", "Global_Time"):  # views of data, not copies
        assert np.shares_memory(out[c].to_numpy(), data), c


def test_unordered_rows_with_duplicates_and_a_lane_filter_read_as_the_sorted_file(tmp_path):
    table = synthetic_table(n_vehicles=30, n_frames=40, seed=2)
    sorted_path = write_ngsim_csv(table, tmp_path / "sorted.csv", precision="exact")
    dup = pd.concat([table, table.iloc[::7]]).sample(frac=1.0, random_state=1)  # exact duplicates, any order
    path = write_ngsim_csv_blocks([dup], tmp_path / "dup.csv", precision="exact")
    load = read_ngsim(path, chunksize=101)  # most rows kept: moved left in place
    assert load.report.duplicate_rows_dropped == len(table.iloc[::7])
    pd.testing.assert_frame_equal(load.table, read_ngsim(sorted_path).table)
    lanes = sorted(table["Lane_ID"].unique())[:2]  # fewer than half the rows kept: copied
    filtered = read_ngsim(path, lanes=lanes, chunksize=101)
    assert 0 < len(filtered.table) < len(table) / 2
    pd.testing.assert_frame_equal(filtered.table, read_ngsim(sorted_path, lanes=lanes).table)
