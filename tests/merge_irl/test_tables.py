"""merge_irl.tables: a table read from a Parquet file, from a Parquet dataset folder (hive partitions
as pandas writes them, or numbered part files as dask writes them), and what is not such a folder."""

import numpy as np
import pandas as pd
import pytest

from merge_irl.tables import is_parquet_dataset, parquet_parts, read_table, table_columns


def _table(n: int = 12) -> pd.DataFrame:
    rng = np.random.default_rng(0)
    return pd.DataFrame({"encounter_id": np.repeat(np.arange(1, n + 1), 3), "x": rng.normal(size=3 * n),
                         "flag": np.tile([True, False, True], n)})


def test_a_hive_partitioned_folder_reads_as_the_file(tmp_path):
    df = _table()
    df.to_parquet(tmp_path / "one.parquet")
    df.to_parquet(tmp_path / "ds", partition_cols=["encounter_id"])
    (tmp_path / "ds" / "_SUCCESS").write_text("")
    assert is_parquet_dataset(tmp_path / "ds") and len(parquet_parts(tmp_path / "ds")) == 12
    got = read_table(tmp_path / "ds")
    assert list(got.columns) == ["x", "flag", "encounter_id"]  # partition column last, as pandas reads it
    assert got["encounter_id"].dtype == np.int64  # not a category: the same values as the file
    # encounter_id=10 after encounter_id=9: natural order, the file's order
    pd.testing.assert_frame_equal(got[df.columns], read_table(tmp_path / "one.parquet"))
    assert sorted(table_columns(tmp_path / "ds")) == sorted(df.columns)


def test_numbered_part_files_read_in_natural_order(tmp_path):
    df = _table()
    (tmp_path / "ds").mkdir()
    for i in range(12):  # part.10 after part.9, as dask numbers them
        df.iloc[3 * i:3 * i + 3].to_parquet(tmp_path / "ds" / f"part.{i}.parquet")
    (tmp_path / "ds" / ".part.3.parquet.crc").write_text("x")
    pd.testing.assert_frame_equal(read_table(tmp_path / "ds", columns=["x", "encounter_id"]),
                                  df[["x", "encounter_id"]])


def test_a_folder_of_different_tables_is_no_dataset(tmp_path):
    _table().to_parquet(tmp_path / "encounters.parquet")
    pd.DataFrame({"y": [1.0]}).to_parquet(tmp_path / "trajectories.parquet")
    (tmp_path / "empty").mkdir()
    assert not is_parquet_dataset(tmp_path) and not is_parquet_dataset(tmp_path / "empty")
    for folder in (tmp_path, tmp_path / "empty"):
        with pytest.raises(KeyError, match="a folder, not a table file or a Parquet dataset folder"):
            read_table(folder, error=KeyError)
