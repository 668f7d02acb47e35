"""``merge-irl evaluate --policy module:callable[:name]``: a researcher's own rule evaluated in
the closed loop beside the baselines (real SUMO, short), and bad specs refused in one line."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

#: A constant-time-headway rule (gap to C towards 2 m + 1.5 s x v_A), returning m/s^2 from the
#: observation in ft and ft/s (sim.drivers.observe.CONTINUOUS_NAMES); the discrete twin returns an index.
CTH_RULE = '''
import math

FT = 0.3048


def cth(obs):
    d_ac, v_ac, d_ab, v_ab, v_a, len_c, len_b = (float(x) for x in obs)
    if d_ac >= 1000.0:  # no lead car (it reads as 1000 ft ahead): towards 28 m/s
        return max(-3.0, min(1.5, 0.3 * (28.0 - v_a * FT)))
    gap = (d_ac - (len_c if math.isfinite(len_c) else 15.0)) * FT
    acc = 0.25 * (gap - (2.0 + 1.5 * v_a * FT)) - 0.6 * v_ac * FT
    return max(-7.0, min(1.5, acc))


def cth_discrete(obs):
    acc = cth(obs)
    return 0 if acc < -1.5 else 1 if acc < -0.2 else 2 if acc < 0.2 else 3


NOT_CALLABLE = 3
'''


def _cli(*args, timeout=300):
    return subprocess.run([sys.executable, "-m", "analysis", "evaluate", *args], capture_output=True, text=True,
                          timeout=timeout)


@pytest.mark.sumo
def test_policy_from_a_file_is_evaluated_beside_the_baselines(tmp_path):
    rule = tmp_path / "rules.py"
    rule.write_text(CTH_RULE)
    out = tmp_path / "ev"
    # two workers: each imports the rule again from its spec (the callable is not pickled)
    r = _cli("--policy", f"{rule}:cth", "--policy", f"{rule}:cth_discrete:cth-discrete", "--baselines", "sumo",
             "--episodes", "1", "--duration", "100", "--seed", "5", "--executor", "process:2", "--no-progress",
             "--out", str(out))
    assert r.returncode == 0, r.stderr
    assert "| cth | 1 |" in r.stdout and "| cth-discrete | 1 |" in r.stdout and "| sumo | 1 |" in r.stdout
    data = json.loads((out / "metrics.json").read_text())
    assert list(data["policies"]) == ["sumo", "cth", "cth-discrete"]
    agg = {k: v["aggregate"] for k, v in data["policies"].items()}
    assert agg["cth"]["n_decisions"] > 0 and agg["cth-discrete"]["n_decisions"] > 0
    counts = agg["cth-discrete"]["action_counts"]
    assert sum(counts) == agg["cth-discrete"]["n_decisions"] and counts[4] == 0  # the rule never returns 4
    md = (out / "report.md").read_text()
    assert "cth-discrete" in md and "| sumo |" in md
    assert (out / "rerun" / "cth.rrd").is_file()
    assert str(rule) in (out / "metrics.json").read_text()  # the rule's file in the provenance


def test_bad_policy_specs_exit_2_with_one_line(tmp_path, capsys):
    from analysis.cli.main import main

    rule = tmp_path / "rules.py"
    rule.write_text(CTH_RULE)
    broken = tmp_path / "broken.py"
    broken.write_text("raise RuntimeError('half written')\n")
    cases = {
        f"{tmp_path / 'nope.py'}:cth": "no such file",
        f"{rule}:missing": "no attribute 'missing'",
        f"{rule}:NOT_CALLABLE": "not callable",
        f"{broken}:f": "RuntimeError: half written",
        "no_such_module_xyz:f": "no module 'no_such_module_xyz'",
        "justonepart": "expected module:callable[:name]",
        f"{rule}:cth:name:extra": "expected module:callable[:name]",
        f"{rule}:cth:a/b": "the name 'a/b' must be letters",  # was rerun/a/b.rrd, a folder made
        f"{rule}:cth:x|y": "the name 'x|y' must be letters",  # was a broken report table row
        f"{rule}:cth:.hidden": "the name '.hidden' must be letters",
    }
    for spec, said in cases.items():
        assert main(["evaluate", "--policy", spec, "--baselines", "", "--out", str(tmp_path / "x")]) == 2, spec
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and said in err, (spec, err)
        assert not (tmp_path / "x").exists()


def test_the_documented_rule_reaches_its_free_road_branch_on_a_policy_observation():
    """policies.md's rule tested ``math.isnan(d_ac)`` for 'no lead car', but a policy never sees
    NaN (no C reads as 1000 ft ahead): it accelerated at 1.5 m/s^2 without a speed target."""
    import re
    from pathlib import Path

    from sim.drivers.observe import policy_rows

    text = (Path(__file__).parents[3] / "docs" / "policies.md").read_text()
    block = re.search(r"<!-- docs-test: file rules.py -->\n```python\n(.*?)```", text, re.S).group(1)
    for source in (block, CTH_RULE):  # the docs' own example and this file's copy
        ns: dict = {}
        exec(source, ns)  # noqa: S102
        fast = policy_rows(np.array([[np.nan, np.nan, -30.0, 0.0, 110.0, np.nan, 15.0]]))[0]  # 33.5 m/s
        assert ns["cth"](fast) < 0  # towards 28 m/s: slower, not the 1.5 m/s^2 of a 300 m gap


@pytest.mark.sumo
def test_the_files_a_policy_loads_are_digested_in_the_provenance(tmp_path):
    import hashlib
    import pickle
    from types import SimpleNamespace

    from analysis.cli.main import main

    rule = tmp_path / "rules.py"
    rule.write_text(CTH_RULE)
    weights = tmp_path / "ppo_merge.zip"
    weights.write_bytes(b"not really a zip, the bytes count")
    stats = tmp_path / "vecnormalize.pkl"  # what with_vecnormalize reads of a VecNormalize.save file
    stats.write_bytes(pickle.dumps(SimpleNamespace(obs_rms=SimpleNamespace(mean=np.zeros(7), var=np.ones(7)),
                                                   norm_obs=True, clip_obs=1e6, epsilon=1e-8)))
    out = tmp_path / "ev"
    assert main(["evaluate", "--policy", f"{rule}:cth", "--policy-weights", str(weights),
                 "--policy-vecnormalize", str(stats), "--baselines", "sumo", "--episodes", "1", "--duration", "90",
                 "--executor", "serial", "--no-rrd", "--no-progress", "--out", str(out)]) == 0
    prov = json.loads((out / "metrics.json").read_text())["provenance"]

    def sha(p):
        return hashlib.sha256(p.read_bytes()).hexdigest()

    assert prov["policy_files"] == {"cth": {"weights": {"path": str(weights), "sha256": sha(weights)},
                                            "vecnormalize": {"path": str(stats), "sha256": sha(stats)}}}
    assert prov["models"]["cth"]["sha256"] == sha(rule) and prov["models"]["sumo"] is None
    md = (out / "report.md").read_text()
    assert f"- policy cth loads weights: `{weights}` sha256 {sha(weights)}" in md
    assert f"- policy cth loads vecnormalize: `{stats}` sha256 {sha(stats)}" in md


def test_policy_weights_that_are_missing_or_without_a_policy_exit_2(tmp_path, capsys):
    from analysis.cli.main import main

    rule = tmp_path / "rules.py"
    rule.write_text(CTH_RULE)
    for args, said in (([f"--policy={rule}:cth", "--policy-weights", str(tmp_path / "nope.zip")],
                        f"--policy-weights {tmp_path / 'nope.zip'}: no such file"),
                       (["--policy-weights", str(rule)], "--policy-weights: give the --policy that loads them")):
        assert main(["evaluate", *args, "--baselines", "sumo", "--out", str(tmp_path / "x")]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and said in err, err
        assert not (tmp_path / "x").exists()
