"""``studies/imitation_bench.py`` and ``studies/gail_diagnosis.py`` run as scripts without torch:
they import and answer ``--help`` without torch, imitation or Stable-Baselines3 and refuse bad
options in one line, and their extra stays out of the default install and the ``test`` extra.
Their torch-free parts are tested beside their modules (tests/studies/support/);
the training and the table need the ``imitation-bench`` extra and run as the study only
(docs/imitation.md)."""

from __future__ import annotations

import os
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]
HEAVY = ("torch", "imitation", "stable_baselines3", "studies.imitation_nets")


def test_the_bench_imports_and_answers_help_without_torch() -> None:
    code = ("import sys, runpy\n"
            "import studies.imitation_bench\n"
            f"heavy = [m for m in {HEAVY!r} if m in sys.modules]\n"
            "assert not heavy, heavy\n"
            "sys.argv = ['imitation_bench', '--help']\n"
            "runpy.run_module('studies.imitation_bench', run_name='__main__')\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "--gail-steps" in r.stdout and "--bc-epochs" in r.stdout


def test_the_imitation_bench_extra_stays_out_of_the_default_install_and_the_tests() -> None:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    extra = project["optional-dependencies"]["imitation-bench"]
    assert "torch==2.13.0" in extra and "imitation==1.0.1" in extra

    def names(reqs: list[str]) -> set[str]:
        return {r.split("[")[0].split("=")[0].split(">")[0].split("<")[0].strip().lower() for r in reqs}

    for where, reqs in (("dependencies", project["dependencies"]),
                        ("test", project["optional-dependencies"]["test"])):
        assert not names(reqs) & {"torch", "imitation", "stable-baselines3"}, where


def test_the_gail_diagnosis_answers_help_and_refuses_a_missing_demo_without_torch(tmp_path: Path) -> None:
    code = ("import sys, runpy\n"
            "import studies.gail_diagnosis\n"
            f"heavy = [m for m in {HEAVY!r} if m in sys.modules]\n"
            "assert not heavy, heavy\n"
            "sys.argv = ['gail_diagnosis', *sys.argv[1:]]\n"
            "runpy.run_module('studies.gail_diagnosis', run_name='__main__')\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    r = subprocess.run([sys.executable, "-c", code, "--help"], cwd=ROOT, env=env, capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "--config" in r.stdout and "--demo" in r.stdout
    r = subprocess.run([sys.executable, "-c", code, "--demo", str(tmp_path), "--config", "{}"], cwd=ROOT, env=env,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "no data/train_encounters.parquet" in r.stderr


def test_the_bench_refuses_a_gail_budget_below_one_round_in_one_line() -> None:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    r = subprocess.run([sys.executable, "-m", "studies.imitation_bench", "--gail-steps", "100"], cwd=ROOT, env=env,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "at least one round" in r.stderr, r.stderr[-2000:]
