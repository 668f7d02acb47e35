"""The README's CI recipe runs as written and passes on a fresh checkout.

The commands are read out of README.md (the fenced shell block that gates with
``check-metrics --fail-if``), so the README and this test cannot drift apart; only the
``pip install`` line is left out (the package under test is already installed).
"""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FENCE = re.compile(r"^```(\w*)[^\n]*\n(.*?)^```", re.DOTALL | re.MULTILINE)


def recipe_commands(readme: Path = ROOT / "README.md") -> list[list[str]]:
    """The ``merge-irl`` commands of the CI recipe in ``readme`` (the one shell block gating with
    ``check-metrics --fail-if``), each as its arguments (without ``merge-irl``), in order."""
    blocks = [body for lang, body in FENCE.findall(readme.read_text(encoding="utf-8"))
              if lang in ("bash", "sh", "shell") and "check-metrics" in body and "--fail-if" in body]
    assert len(blocks) == 1, f"{readme.name}: expected one shell block gating with check-metrics, found {len(blocks)}"
    commands = []
    for line in blocks[0].replace("\\\n", " ").splitlines():
        words = shlex.split(line, comments=True)
        if not words or words[0] in ("set", "export") or words[:2] == ["pip", "install"]:
            continue
        assert words[0] == "merge-irl", f"{readme.name} CI recipe: unexpected command {line!r}"
        commands.append(words[1:])
    return commands


def _option(args: list[str], name: str) -> list[str]:
    return [args[i + 1] for i, a in enumerate(args) if a == name]


def test_the_recipe_gates_the_learned_driver_it_trains():
    cmds = {c[0]: c for c in recipe_commands()}
    assert list(cmds) == ["generate", "learn-driver", "evaluate", "check-metrics"]
    driver = _option(cmds["learn-driver"], "--out")[0]
    assert _option(cmds["evaluate"], "--driver") == [driver]
    gates = _option(cmds["check-metrics"], "--fail-if")
    assert gates and all(g.startswith(Path(driver).stem + ".") for g in gates), gates  # not a baseline, not Q-Avg
    assert cmds["check-metrics"][1] == str(Path(_option(cmds["evaluate"], "--out")[0]) / "metrics.json")


def test_the_ci_page_shows_the_readme_recipe():
    assert recipe_commands(ROOT / "docs" / "ci.md") == recipe_commands()


@pytest.mark.sumo
def test_the_readme_ci_recipe_passes_as_written(tmp_path):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
           "MPLBACKEND": "Agg"}
    results = []
    for args in recipe_commands():
        r = subprocess.run([sys.executable, "-m", "analysis", *args], cwd=tmp_path, env=env, capture_output=True,
                           text=True, timeout=900)
        assert r.returncode == 0, f"merge-irl {shlex.join(args)}: exit {r.returncode}\n{r.stderr[-3000:]}"
        results.append((args, r))
    args, last = results[-1]
    assert args[0] == "check-metrics"
    gates = _option(args, "--fail-if")
    assert all(f"gate {g} not triggered" in last.stderr for g in gates), last.stderr
    # the gate had something to judge: the driver controlled As in every episode
    metrics = json.loads((tmp_path / args[1]).read_text())
    policy = gates[0].split(".")[0]
    agg = metrics["policies"][policy]["aggregate"]
    assert agg["n_controls"] > 0 and agg["n_decisions"] > 0 and agg["n_episodes"] == len(
        metrics["policies"][policy]["episodes"])
