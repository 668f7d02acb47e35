"""A driver whose held-out log-likelihood per step is below uniform actions' is flagged in the
evaluation (metrics, report and the command's warning line), not reported like any other."""

from __future__ import annotations

import numpy as np
import pytest
from irl_testdata import encounter_table

from analysis.evaluation.evaluate import evaluate
from analysis.evaluation.outcome import UNIFORM_LL_PER_STEP, heldout_flags
from analysis.evaluation.report import flag_lines
from irl.config import IRLConfig
from irl.domains.merge.bins import MergeBins
from irl.domains.merge.features import FEATURE_NAMES
from irl.result import SavedModel


def _model(tmp_path, q_scale: float):
    rng = np.random.default_rng(3)
    edges = MergeBins.assumed_authors()
    m = SavedModel(method="qavg", theta=np.array([1.0, 0.5, -0.2]), loglik=-1.0,
                   q=rng.normal(size=(1250, 5)) * q_scale, config=IRLConfig(beta=1.0), domain="merge",
                   feature_names=FEATURE_NAMES, bin_edges={k: tuple(v) for k, v in edges.to_dict().items()})
    return m.save(tmp_path / f"q{int(q_scale)}.json")


def test_flag_rule() -> None:
    assert UNIFORM_LL_PER_STEP == pytest.approx(-1.6094, abs=1e-4)
    assert heldout_flags((-315.0, -3.15)) == ("heldout_worse_than_uniform",)
    assert heldout_flags((-100.0, -1.0)) == () and heldout_flags(None) == ()
    assert heldout_flags((float("nan"), float("nan"))) == ()


@pytest.mark.sumo
def test_a_driver_worse_than_uniform_on_held_out_data_is_flagged(tmp_path) -> None:
    demos = tmp_path / "heldout.parquet"
    encounter_table(n=4, rows=60).to_parquet(demos)
    bad = _model(tmp_path, 30.0)  # confident and random: far below uniform on any data
    rep = evaluate([bad], "synthetic", 1, 2, tmp_path / "ev", duration_s=90, demos=demos, baselines=["uniform"],
                   rrd=False, progress=False, executor="serial")
    assert set(rep.aggregates) == {"q30", "uniform"}
    worse, uniform = rep.aggregates["q30"], rep.aggregates["uniform"]
    assert uniform.heldout_loglik_per_step == pytest.approx(UNIFORM_LL_PER_STEP, abs=1e-9)
    assert worse.heldout_loglik_per_step < UNIFORM_LL_PER_STEP
    assert "heldout_worse_than_uniform" in worse.flags and worse.flagged == 1 and not uniform.flags
    lines = flag_lines(rep.aggregates)
    assert len(lines) == 1 and "worse than chance" in lines[0] and "did not reach a usable maximum" not in lines[0]
    assert "heldout_worse_than_uniform" in (tmp_path / "ev" / "metrics.json").read_text()
