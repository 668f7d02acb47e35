"""merge_irl.atomic: the project's one atomic writer (complete file or none; mode 0666 minus umask)."""

import ast
import os
import stat
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis.calibration.models import CFParams
from analysis.calibration.params_file import load_result, save_result
from analysis.calibration.result import CalibrationResult
from analysis.evaluation.plots import _plt, _save
from merge_irl.atomic import temporary_path, write_atomic, write_json_atomic, write_text_atomic
from scenarios.loader import load_scenario
from scenarios.network import build_network

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(params=[0o022, 0o027, 0o002])
def umask(request):
    old = os.umask(request.param)
    yield request.param
    os.umask(old)


def _mode(p: Path) -> int:
    return stat.S_IMODE(p.stat().st_mode)


def test_files_get_the_mode_a_plain_open_gives(tmp_path, umask):
    expected = 0o666 & ~umask
    plain = tmp_path / "plain.parquet"
    pd.DataFrame({"a": [1, 2]}).to_parquet(plain)  # what the Parquet files get
    assert _mode(plain) == expected
    written = [
        write_text_atomic(tmp_path / "report.md", "# r\n"),
        write_json_atomic(tmp_path / "sub" / "model.json", {"theta": [1.0]}),
        write_atomic(tmp_path / "t.parquet", lambda p: pd.DataFrame({"a": [1]}).to_parquet(p)),
        write_atomic(tmp_path / "x.npz", lambda p: np.savez(open(p, "wb"), a=np.arange(3))),
    ]
    for p in written:
        assert _mode(p) == expected, f"{p.name}: {oct(_mode(p))} != {oct(expected)}"
    assert umask != 0o022 or expected == 0o644


def test_calibration_file_and_plot_are_0644_under_umask_022(tmp_path):
    result = CalibrationResult(model="idm", fitted=("tau",), population=CFParams(), population_median_rmse_m=1.5,
                               per_pair=(), spread=(), n_pairs=3, seconds_population=0.1, seconds_per_pair=0.0)
    fig = _plt().figure()
    old = os.umask(0o022)
    try:
        cal = save_result(result, tmp_path / "cal.toml")
        png = _save(fig, tmp_path / "plot.png")
    finally:
        os.umask(old)
    assert _mode(cal) == 0o644
    assert _mode(png) == 0o644
    assert load_result(cal) == result
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cal.toml", "plot.png"]  # no temporary left


def test_failed_write_keeps_the_old_file_and_leaves_no_temporary(tmp_path):
    target = write_text_atomic(tmp_path / "m.json", "old")

    def broken(p: Path) -> None:
        p.write_text("half")
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError, match="disk full"):
        write_atomic(target, broken)
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["m.json"]


def test_temporary_names_are_hidden_fresh_and_keep_the_suffix(tmp_path):
    a, b = temporary_path(tmp_path / "plot.png"), temporary_path(tmp_path / "plot.png")
    assert a != b and a.exists() and b.exists()
    assert a.name.startswith(".plot.png.") and a.suffix == ".png"
    assert temporary_path(tmp_path / "r.rrd", suffix=".partial").suffix == ".partial"


def _renames_or_temp_files(tree: ast.AST) -> list[str]:
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            name = node.func.attr
            owner = node.func.value.id if isinstance(node.func.value, ast.Name) else ""
            if (owner == "os" and name in ("replace", "rename")) or (
                    owner == "tempfile" and name in ("mkstemp", "NamedTemporaryFile")):
                found.append(f"{owner}.{name} line {node.lineno}")
    return found


def test_atomic_is_the_only_file_writer_that_renames():
    """Every other module writes through merge_irl.atomic. scenarios/network.py and merge_irl/run_folder.py
    rename whole directories (the netconvert cache, a run's staging folder), not file writes."""
    allowed = {"merge_irl/atomic.py": None, "scenarios/network.py": ["os.rename"], "merge_irl/run_folder.py": ["os.rename"]}
    offenders = {}
    for top in ("merge_irl", "sim", "irl", "scenarios", "analysis", "benchmarks", "studies", "tools"):
        for path in sorted((ROOT / top).rglob("*.py")):
            rel = path.relative_to(ROOT).as_posix()
            hits = _renames_or_temp_files(ast.parse(path.read_text(encoding="utf-8")))
            if rel in allowed:
                ok = allowed[rel]
                hits = [] if ok is None else [h for h in hits if h.split(" ")[0] not in ok]
            if hits:
                offenders[rel] = hits
    assert offenders == {}


def test_network_cache_folder_is_readable_like_the_files(tmp_path):
    old = os.umask(0o022)
    try:
        net = build_network(load_scenario("synthetic").road, cache_dir=tmp_path)
    finally:
        os.umask(old)
    assert _mode(net.parent) == 0o755
    assert _mode(net) == 0o644


def test_a_failed_write_that_names_no_file_is_reported_with_the_path(tmp_path):
    """A full disk seen by a library's writer (pyarrow, a plain write()) names no file: the error
    that reaches the user names the file being written."""
    import errno

    from analysis.cli.main import os_error_line

    target = tmp_path / "out" / "table.parquet"

    def disk_full(p: Path) -> None:
        p.write_bytes(b"partial")
        raise OSError(errno.ENOSPC, "Error writing bytes to file. Detail: [errno 28] No space left on device")

    with pytest.raises(OSError) as caught:
        write_atomic(target, disk_full)
    assert caught.value.errno == errno.ENOSPC
    assert os_error_line(caught.value) == f"No space left on device: {target}"
    assert list(target.parent.iterdir()) == []  # the temporary is gone
