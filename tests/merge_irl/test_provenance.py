"""Provenance of outputs (versions, git commit, input hashes) and byte-identical reruns."""

import hashlib
import json
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis.cli.main import main
from irl.result import SavedModel
from merge_irl import provenance as prov

ROOT = Path(__file__).resolve().parents[2]
HAVE_GIT = shutil.which("git") is not None


def _encounter_table(path: Path, seed: int = 0) -> Path:
    rng = np.random.default_rng(seed)
    n, rows = 4, 30
    pd.DataFrame({
        "encounter_id": np.repeat(np.arange(n), rows), "frame": np.tile(np.arange(rows), n),
        "d_AC": rng.uniform(10, 150, n * rows), "d_AB": rng.uniform(0, 80, n * rows),
        "v_AC": rng.normal(0, 5, n * rows), "v_AB": rng.normal(0, 5, n * rows),
        "B_is_truck": np.repeat([0, 1, 0, 0], rows), "acc_A": rng.normal(0, 3, n * rows),
    }).to_parquet(path)
    return path


def test_file_digest_is_sha256_of_the_bytes(tmp_path):
    f = tmp_path / "a.bin"
    data = bytes(range(256)) * 5000  # > one read chunk
    f.write_bytes(data)
    assert prov.path_digest(f) == {"path": str(f), "sha256": hashlib.sha256(data).hexdigest()}


def test_folder_digest_changes_with_any_file_name_or_content(tmp_path):
    d = tmp_path / "demos"
    (d / "sub").mkdir(parents=True)
    (d / "a.txt").write_text("1 2 3\n")
    (d / "sub" / "b.txt").write_text("4 5\n")
    first = prov.path_digest(d)
    assert first["files"] == 2
    assert prov.path_digest(d) == first
    (d / "sub" / "b.txt").write_text("4 6\n")
    second = prov.path_digest(d)
    assert second["sha256"] != first["sha256"]
    (d / "sub" / "b.txt").rename(d / "sub" / "c.txt")
    assert prov.path_digest(d)["sha256"] not in (first["sha256"], second["sha256"])


def test_missing_input_is_a_file_not_found_error(tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.parquet"):
        prov.provenance({"demos": tmp_path / "nope.parquet"})


def test_record_lists_versions_inputs_and_models(tmp_path):
    f = tmp_path / "qavg.json"
    f.write_text("{}")
    r = prov.provenance({"demos": f, "baseline": None}, {"qavg": f, "sumo": None}, extra={"scenario_sha256": "x"})
    assert r["merge_irl"] == prov.package_version() and r["sumo"] == prov.sumo_version()
    assert set(r["inputs"]) == {"demos"}
    assert r["models"] == {"qavg": {"path": str(f), "sha256": hashlib.sha256(b"{}").hexdigest()}, "sumo": None}
    assert r["scenario_sha256"] == "x"
    json.dumps(r)  # JSON-ready


def test_files_a_policy_loads_are_digested_per_policy_and_listed(tmp_path):
    w, vn = tmp_path / "w.zip", tmp_path / "vn.pkl"
    w.write_bytes(b"weights")
    vn.write_bytes(b"stats")
    rec = prov.provenance(policy_files={"ppo": {"weights": w, "vecnormalize": vn}, "rule": {}})
    assert rec["policy_files"] == {"ppo": {"weights": {"path": str(w), "sha256": hashlib.sha256(b"weights").hexdigest()},
                                           "vecnormalize": {"path": str(vn), "sha256": hashlib.sha256(b"stats").hexdigest()}}}
    md = prov.provenance_markdown(rec)
    assert f"- policy ppo loads weights: `{w}` sha256 {hashlib.sha256(b'weights').hexdigest()}" in md
    assert "policy_files" not in md  # listed, not dumped
    assert "policy_files" not in prov.provenance(policy_files={"rule": {}})  # nothing loaded: no entry
    with pytest.raises(FileNotFoundError, match="no such input file"):
        prov.provenance(policy_files={"ppo": {"weights": tmp_path / "gone.zip"}})


def test_installed_version_is_the_source_version():
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert prov.package_version() == meta["project"]["version"]
    assert prov.sumo_version() is not None and prov.sumo_version().startswith("1.")


@pytest.mark.skipif(not HAVE_GIT, reason="git is not installed")
def test_git_state_only_at_the_top_of_a_checkout(tmp_path):
    repo = tmp_path / "repo"
    (repo / "pkg").mkdir(parents=True)
    (repo / "pkg" / "m.py").write_text("x = 1\n")
    env = ["-c", "user.name=t", "-c", "user.email=t@t"]
    subprocess.run(["git", "init", "-q", str(repo)], check=True)
    subprocess.run(["git", "-C", str(repo), "add", "."], check=True)
    subprocess.run(["git", "-C", str(repo), *env, "commit", "-qm", "c"], check=True)
    head = subprocess.run(["git", "-C", str(repo), "rev-parse", "HEAD"], capture_output=True, text=True,
                          check=True).stdout.strip()
    assert prov.git_state.__wrapped__(repo) == (head, False)
    (repo / "untracked.txt").write_text("not part of the code")
    assert prov.git_state.__wrapped__(repo) == (head, False)
    (repo / "pkg" / "m.py").write_text("x = 2\n")
    assert prov.git_state.__wrapped__(repo) == (head, True)
    # a folder inside a checkout (say, site-packages in a project's venv) is not that checkout
    assert prov.git_state.__wrapped__(repo / "pkg") is None
    assert prov.git_state.__wrapped__(tmp_path) is None


def test_version_option_prints_versions_without_importing_libsumo():
    code = ("import sys\nfrom analysis.cli.main import main\n"
            "try:\n    main(['--version'])\nexcept SystemExit as e:\n    assert e.code in (0, None), e.code\n"
            "assert 'libsumo' not in sys.modules, 'libsumo imported'\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=False)
    assert r.returncode == 0, r.stderr
    line = r.stdout.strip()
    assert line.startswith(f"merge-irl {prov.package_version()} (SUMO {prov.sumo_version()}")
    state = prov.git_state()
    if state is not None:
        assert state[0][:12] in line


def _learn(demos: Path, out: Path, *extra: str) -> SavedModel:
    rc = main(["learn", "--method", "qavg", "--domain", "merge", "--demos", str(demos), "--settings", "reference",
               "--seed", "4", "--out", str(out), "--no-progress", *extra])
    assert rc == 0
    return SavedModel.load(out)


def test_two_identical_learn_runs_write_byte_identical_models(tmp_path, capsys):
    demos = _encounter_table(tmp_path / "enc.parquet")
    a = _learn(demos, tmp_path / "a" / "model.json")
    b = _learn(demos, tmp_path / "b" / "model.json")
    assert (tmp_path / "a" / "model.json").read_bytes() == (tmp_path / "b" / "model.json").read_bytes()
    assert "wall_time" not in (tmp_path / "a" / "model.json").read_text()
    # the time is kept, beside the model
    t = json.loads((tmp_path / "a" / "model.timings.json").read_text())
    assert t["fit_wall_time_s"] > 0
    p = a.info["provenance"]
    assert p == b.info["provenance"]
    assert p["inputs"]["demos"]["sha256"] == hashlib.sha256(demos.read_bytes()).hexdigest()
    assert p["merge_irl"] == prov.package_version() and p["sumo"] == prov.sumo_version()
    state = prov.git_state()
    assert ("git_commit" in p) == (state is not None)
    if state is not None:
        assert p["git_commit"] == state[0]


def test_learn_records_the_bins_file_it_read(tmp_path, capsys):
    demos = _encounter_table(tmp_path / "enc.parquet")
    m = _learn(demos, tmp_path / "m.json")
    bins = tmp_path / "bins.json"
    bins.write_text(json.dumps({k: list(v) for k, v in m.bin_edges.items()}))
    m2 = _learn(demos, tmp_path / "m2.json", "--bins", str(bins))
    assert m2.info["provenance"]["inputs"]["bins"]["sha256"] == hashlib.sha256(bins.read_bytes()).hexdigest()
    assert m2.bin_edges == m.bin_edges
    # other data, other hash
    other = _encounter_table(tmp_path / "enc2.parquet", seed=1)
    m3 = _learn(other, tmp_path / "m3.json")
    assert m3.info["provenance"]["inputs"]["demos"]["sha256"] != m.info["provenance"]["inputs"]["demos"]["sha256"]
