"""The whole pipeline on one scenario, in one call (``merge-irl demo``).

:func:`run_demo`:

1. **generate** merges: simulate the scenario with SUMO's own drivers for the training seeds and
   the held-out seeds (one run by default; in worker processes), extract the merge encounters
   (``sim.merges.demonstrators``);
2. **discretize**: quantile bin edges fitted on the training encounters (``irl.domains.merge.bins``);
   encounter frames without a lead car C get the closed loop's open-road values;
3. **learn** Q-Avg by default (MLIRL, Q-SM and REIRL on request; ``analysis.experiments.learn``) with the
   settings of ``merge-irl learn`` on encounter tables (driver features and state encoding,
   beta 1: :func:`analysis.experiments.learn.merge_config`) and gamma ``DemoConfig.gamma`` (0, chosen by
   held-out log-likelihood), one ``model.json`` each; then the car-following logit driver
   ``cf-dagger`` (``DemoConfig.dagger_rounds`` DAgger rounds, ``analysis.experiments.dagger``;
   0, the default: left out; ``merge-irl demo --with-dagger``: 4);
4. **re-inject and evaluate**: every model (and ``cf-dagger``) drive the lag cars A of new
   episodes (other seeds), beside SUMO's own driver and the baselines uniform, marginal, markov
   and bc (``analysis.evaluation``: planned, run and reported), with the held-out encounters for the held-out
   log-likelihood and the Wasserstein distances;
5. **log**: ``demo.rrd`` holds the IRL training traces of every method and one closed-loop
   episode driven by Q-Avg (vehicles, policy, metrics); the evaluation adds one ``.rrd`` per
   policy.

Everything goes under ``out_dir`` (default ``./runs/demo``)::

    data/train_encounters.parquet, data/heldout_encounters.parquet, data/bins.json
    models/<method>.json, models/cf-dagger.json, models/cf-logit.json (DAgger's round 0)
    evaluation/report.md, metrics.json, *.png, rerun/<policy>.rrd
    demo.rrd
    summary.md      (with the provenance: versions, git commit, scenario and model hashes)
    timings.json    (wall times, also per part: kept out of the results so reruns can be compared by hash)

Before any work it prints one line saying how long it expects to take here
(:mod:`analysis.demo.estimate`: the cores, the load average and the demo's measured CPU time).
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from analysis.demo.config import CF_DRIVER, PLANNER_DRIVER, DemoConfig, check_dagger_seeds
from analysis.demo.estimate import estimate
from analysis.errors import AnalysisError
from analysis.evaluation.config import EvaluationConfig
from analysis.evaluation.episode import frame_from_dict, frame_to_dict
from analysis.evaluation.outcome import EvaluationReport, write_report
from analysis.evaluation.plan import plan_evaluation
from analysis.evaluation.policies import learned_policy
from analysis.evaluation.report import collision_bound_line, flag_lines, human_table, report_table
from analysis.evaluation.run import run_plan
from analysis.experiments.dagger import DaggerConfig, train_cf_driver
from analysis.experiments.learn import fit_problem, merge_config, merge_encoding, merge_features, saved_model
from analysis.sweep import Task, resolve_executor, run_sweep
from irl.domains.merge.bins import fit_quantile_bins
from irl.domains.merge.encounters import prepare_encounters
from irl.errors import IRLError
from irl.methods.registry import method_names
from irl.planning.decisions import encounter_decisions
from irl.planning.driver import learn_planning_driver
from irl.planning.model import LIKELIHOOD_ROAD_MODEL, PlannerConfig
from irl.problems import load_problem
from merge_irl.atomic import write_text_atomic
from merge_irl.provenance import provenance, provenance_markdown, text_digest, write_timings
from scenarios.loader import load_scenario
from scenarios.spec.model import ScenarioSpec
from sim.closed_loop.controller import Controller
from sim.drivers.learned import CarFollowingLogitPolicy
from sim.drivers.planning import PlanningDriverPolicy
from sim.drivers.policy import Policy
from sim.merges.demonstrators import simulate_demonstrations
from sim.merges.rules import ENCOUNTER_RULES
from sim.runtime.outputs import write_parquet
from sim.runtime.run import run_scenario


@dataclass(frozen=True)
class DemoResult:
    """Where everything is, plus the evaluation."""

    out_dir: Path
    models: dict[str, Path]
    evaluation: EvaluationReport
    demo_rrd: Path
    summary_md: Path
    n_train_encounters: int
    n_train_steps: int
    wall_time_s: float
    fit_messages: dict[str, str] = field(default_factory=dict)
    encounter_rule: str = ENCOUNTER_RULES[0]
    n_heldout_encounters: int = 0
    heldout_runs: int = 1

    def format(self, *, timings: bool = True) -> str:
        """The summary printed by ``merge-irl demo``; ``timings=False``: without the wall time
        (as in ``summary.md``, so reruns can be compared by hash)."""
        lines = [
            f"merge-irl demo -> {self.out_dir}" + (f"  ({self.wall_time_s:.0f} s)" if timings else ""),
            f"  training data: {self.n_train_encounters} encounters, {self.n_train_steps} steps "
            f"({self.encounter_rule} demonstrations)",
            f"  held-out data: {self.n_heldout_encounters} encounters from {self.heldout_runs} "
            f"run{'s' * (self.heldout_runs > 1)}",
            "  models: " + ", ".join(f"{k} {v}" for k, v in self.models.items()),
            *[f"  left out: {k} ({v})" for k, v in self.fit_messages.items() if k not in self.models],
            "",
            report_table(self.evaluation.aggregates),
            "  human likeness:",
            human_table(self.evaluation.aggregates, self.evaluation.demo_closeness),
            *flag_lines(self.evaluation.aggregates),
            "  " + collision_bound_line(self.evaluation.aggregates),
            "",
            f"  report:  {self.evaluation.report_md}",
            f"  metrics: {self.evaluation.metrics_json}",
            f"  rerun:   {self.demo_rrd}   (merge-irl view {self.out_dir})",
            f"  summary: {self.summary_md}",
        ]
        return "\n".join(lines)


@dataclass(frozen=True)
class EncounterRun:
    """One data run as a sweep task config: ``scenario`` (name, TOML path or ScenarioSpec)
    simulated with SUMO ``seed`` for ``duration_s`` (None: the scenario's), its encounters cut by
    ``encounter_rule`` (:mod:`sim.merges.demonstrators`)."""

    scenario: str | Path | ScenarioSpec
    seed: int
    duration_s: float | None = None
    encounter_rule: str = ENCOUNTER_RULES[0]


def encounters_task(run: EncounterRun, seed: int) -> dict:
    """Sweep task: the run's encounter frames (ids offset by ``1e6 * run.seed``) as
    ``analysis.evaluation.episode.frame_to_dict``. The sweep's derived ``seed`` is not used."""
    del seed
    spec = load_scenario(run.scenario) if isinstance(run.scenario, (str, Path)) else run.scenario
    _, enc = simulate_demonstrations(spec, run.encounter_rule, seed=run.seed, duration_s=run.duration_s)
    frames = enc.frames  # with A's speed v_A
    frames["encounter_id"] = frames["encounter_id"].astype("int64") + 1_000_000 * int(run.seed)
    return frame_to_dict(frames)


def generate_encounters(scenario, seeds: Sequence[int], duration_s: float | None, *, workers: int | None = 2,
                        executor: str | None = None, progress: bool = False,
                        encounter_rule: str = ENCOUNTER_RULES[0]) -> list[pd.DataFrame]:
    """Encounter frames of one SUMO run per seed, ids made unique per seed, in seed order,
    cut by ``encounter_rule`` (:mod:`sim.merges.demonstrators`).

    Runs through :func:`analysis.sweep.run_sweep` (``executor``, default ``process:<workers>``;
    one simulation per worker process at a time). Raises AnalysisError if a run failed twice.

    Raises:
        AnalysisError: a data run failed (the message lists each failed run and its error).
    """
    tasks = [Task(f"{i:03d}/seed{int(s)}", encounters_task, EncounterRun(scenario, int(s), duration_s, encounter_rule))
             for i, s in enumerate(seeds)]
    report = run_sweep(tasks, seed=0, executor=resolve_executor(executor, workers),
                       progress=progress, desc="data runs")
    if not report.ok:
        raise AnalysisError("data runs failed: " + "; ".join(f"{f.key}: {f.error}" for f in report.failures))
    return [frame_from_dict(report.results[t.key]) for t in tasks]


def _say(msg: str, quiet: bool) -> None:
    if not quiet:
        print(msg, file=sys.stderr, flush=True)


def run_demo(out_dir: str | Path | None = None, config: DemoConfig = DemoConfig(), *, quiet: bool = False,
             progress: bool = True) -> DemoResult:
    """Run the whole pipeline (see the module docstring) and return where the outputs are.

    Raises:
        IRLError: no IRL method produced a usable model (the message gives each method's reason).
    """
    # rerun takes about 0.8 s to import; the sweep workers that import this module for
    # encounters_task never record
    from analysis.recording.files import close_recording, open_recording, recording_identity, run_token
    from analysis.recording.log import RerunLogger

    t0 = time.perf_counter()
    check_dagger_seeds(config)  # before any work
    out = Path(out_dir) if out_dir is not None else Path("runs") / "demo"
    spec0 = load_scenario(config.scenario)
    _say(estimate(config, spec0).line(), quiet)
    (out / "data").mkdir(parents=True, exist_ok=True)
    phases: dict[str, float] = {}
    t_phase = time.perf_counter()

    def phase(name: str) -> None:  # wall seconds per part, into timings.json
        nonlocal t_phase
        now = time.perf_counter()
        phases[name] = now - t_phase
        t_phase = now

    n_held = config.heldout_runs
    _say(f"[1/5] simulating {len(config.train_seeds)} training runs + {n_held} held-out run{'s' * (n_held > 1)} "
         f"of {config.scenario}", quiet)
    frames = generate_encounters(config.scenario, (*config.train_seeds, *config.heldout_seeds),
                                 config.data_duration_s, workers=config.workers,
                                 executor=config.executor, encounter_rule=config.encounter_rule)
    n_train = len(config.train_seeds)
    train = prepare_encounters(pd.concat(frames[:n_train], ignore_index=True))
    heldout = prepare_encounters(pd.concat(frames[n_train:], ignore_index=True))
    train_path = out / "data" / "train_encounters.parquet"
    held_path = out / "data" / "heldout_encounters.parquet"
    for df, path in ((train, train_path), (heldout, held_path)):
        write_parquet(df, path)

    phase("data_runs")
    _say("[2/5] discretizing (quantile bins fitted on the training encounters)", quiet)
    bins = fit_quantile_bins(train, where=str(train_path))
    bins.save(out / "data" / "bins.json")
    features = merge_features(train_path, config.features)
    problem = load_problem("merge", train_path, bins=bins, name=f"{config.scenario} training encounters",
                           encoding=merge_encoding(features), features=features)
    model_prov = provenance({"demos": train_path, "bins": out / "data" / "bins.json"})

    _say(f"[3/5] learning {', '.join(config.methods)}", quiet)
    rid, name = recording_identity(config.scenario, "demo", config.eval_seed, run=run_token(out / "demo.rrd"))
    rec, tmp_rrd = open_recording(out / "demo.rrd", recording_id=rid, name=f"{name}: training and one episode")
    models, messages, fit_times = _fit_methods(config, problem, rec, train_path, model_prov, out, quiet)
    if not models:
        raise IRLError("demo: no IRL method produced a usable model: " + "; ".join(f"{k}: {v}" for k, v in messages.items()))
    phase("irl_fits")
    drivers = _cf_drivers(config, train, train_path, out, models, fit_times, quiet)
    phase("cf_dagger")
    # the planning driver, from the demonstrations alone, at the settings the held-out selection of
    # `merge-irl learn-driver` chose on this scenario's data (PlannerConfig's defaults; docs/closed-loop.md)
    drivers.append(_planning_driver(config, train, train_path, out, models, fit_times, quiet))
    phase("planner")
    _say("[4/5] one closed-loop episode with Q-Avg, logged to demo.rrd", quiet)
    first = "qavg" if "qavg" in models else next(iter(models))
    pol = learned_policy(models[first])
    logger = RerunLogger(out / "demo.rrd", recording=(rec, tmp_rrd), training_methods=config.methods)
    # the logger needs the episode's controller: run_episode builds it, so attach via extra hook
    _run_logged_episode(config, pol, logger)
    close_recording(rec, tmp_rrd, out / "demo.rrd")
    phase("logged_episode")

    _say(f"[5/5] evaluating {len(models)} model{'s' * (len(models) > 1)} + sumo, uniform, marginal, markov, bc, "
         f"{config.eval_episodes} episodes each", quiet)
    irl_models = [path for name, path in models.items() if name not in (CF_DRIVER, "cf-logit", PLANNER_DRIVER)]
    plan = plan_evaluation(EvaluationConfig(
        config.scenario, config.eval_episodes, config.eval_seed, out / "evaluation", drivers=(*irl_models, *drivers),
        duration_s=config.eval_duration_s, demos=held_path, train_demos=train_path, workers=config.workers,
        executor=config.executor, progress=progress))
    report = write_report(plan, run_plan(plan))
    phase("evaluation")
    wall = time.perf_counter() - t0
    result = DemoResult(out, models, report, out / "demo.rrd", out / "summary.md", int(train["encounter_id"].nunique()),
                        problem.demos.n_steps, wall, messages, config.encounter_rule,
                        int(heldout["encounter_id"].nunique()), config.heldout_runs)
    scenario_file = config.scenario if Path(config.scenario).is_file() else None
    summary_prov = provenance({"scenario": scenario_file}, models,
                              extra={"scenario_sha256": text_digest(load_scenario(config.scenario).to_toml())})
    write_text_atomic(out / "summary.md", "# merge-irl demo\n\n```\n" + result.format(timings=False) + "\n```\n\n"
                      + provenance_markdown(summary_prov) + "\n")
    write_timings(out, {"wall_time_s": wall, "fit_wall_time_s": fit_times, "phase_wall_s": phases})
    _remove_stale_models(out / "models", written=set(models.values()))
    return result


def _fit_methods(config: DemoConfig, problem, rec, train_path: Path, model_prov: dict, out: Path,
                 quiet: bool) -> tuple[dict[str, Path], dict[str, str], dict[str, float]]:
    """Fit every IRL method of ``config`` (each logged into the recording ``rec``) and save the
    usable models to ``out/models/<method>.json``: ``(models, messages, fit wall seconds)``."""
    from analysis.recording.log import log_training  # rerun: imported only when recording

    models: dict[str, Path] = {}
    messages: dict[str, str] = {}
    fit_times: dict[str, float] = {}
    for method in config.methods:
        cfg = merge_config(gamma=config.gamma, l2=config.l2, method=method)
        fit = fit_problem(problem, method, cfg, config.fit_seed, progress=False)
        messages[method] = fit.message
        fit_times[method] = float(fit.wall_time_s)
        log_training(rec, method, fit.loglik_trace, fit.theta_trace, problem.feature_names)
        usable = math.isfinite(fit.loglik) and np.all(np.isfinite(fit.q)) and np.all(np.isfinite(fit.theta))
        _say(f"      {method}: loglik {fit.loglik:.2f}, theta {[round(float(x), 3) for x in fit.theta]} "
             f"({fit.wall_time_s:.2f} s){' FLAGGED ' + ', '.join(fit.flags) if fit.flags else ''}"
             f"{'' if usable else ' -- not usable, left out: ' + fit.message}", quiet)
        if usable:
            model = saved_model(fit, problem, seed=config.fit_seed, source=str(train_path), provenance=model_prov,
                                unvisited=config.unvisited)
            models[method] = model.save(out / "models" / f"{method}.json")
    return models, messages, fit_times


def _cf_drivers(config: DemoConfig, train: pd.DataFrame, train_path: Path, out: Path, models: dict[str, Path],
                fit_times: dict[str, float], quiet: bool) -> list[Policy]:
    """``cf-dagger`` and its round 0 ``cf-logit`` (saved, added to ``models`` and ``fit_times``),
    or none with ``dagger_rounds`` 0."""
    drivers: list[Policy] = []
    if config.dagger_rounds > 0:
        t_cf = time.perf_counter()
        cf = train_cf_driver(train, config.scenario, DaggerConfig(rounds=config.dagger_rounds), workers=config.workers,
                             executor=config.executor, where=str(train_path), progress=not quiet)
        models[CF_DRIVER] = cf[-1].save(out / "models" / "cf-dagger.json")
        models["cf-logit"] = cf[0].save(out / "models" / "cf-logit.json")  # round 0, the demonstrations alone
        drivers.append(CarFollowingLogitPolicy(cf[-1], name=CF_DRIVER, source=str(models[CF_DRIVER])))
        drivers.append(CarFollowingLogitPolicy(cf[0], name="cf-logit", source=str(models["cf-logit"])))
        fit_times[CF_DRIVER] = time.perf_counter() - t_cf
        _say(f"      {CF_DRIVER}: {config.dagger_rounds} DAgger rounds, High Brake labels per round "
             f"{cf[-1].info['labels_per_round']} ({fit_times[CF_DRIVER]:.0f} s)"
             f"{'' if cf[-1].converged else ' FLAGGED not_converged'}", quiet)
    return drivers


def _planning_driver(config: DemoConfig, train: pd.DataFrame, train_path: Path, out: Path, models: dict[str, Path],
                     fit_times: dict[str, float], quiet: bool) -> Policy:
    """The planning driver from the demonstrations alone, at the settings the held-out selection of
    ``merge-irl learn-driver`` chose on this scenario's data (saved, added to ``models`` and ``fit_times``)."""
    t_pl = time.perf_counter()
    planner = learn_planning_driver(encounter_decisions(train, where=str(train_path)), seed=config.fit_seed,
                                    selection=PlannerConfig(road_model=LIKELIHOOD_ROAD_MODEL))
    models[PLANNER_DRIVER] = planner.save(out / "models" / f"{PLANNER_DRIVER}.json")
    fit_times[PLANNER_DRIVER] = time.perf_counter() - t_pl
    _say(f"      {PLANNER_DRIVER}: {planner.info['n_decisions']} decisions, loglik "
         f"{planner.loglik / planner.info['n_decisions']:.3f} per decision ({fit_times[PLANNER_DRIVER]:.1f} s)"
         f"{'' if planner.converged else ' FLAGGED not_converged'}", quiet)
    return PlanningDriverPolicy(planner, name=PLANNER_DRIVER, source=str(models[PLANNER_DRIVER]))


def _remove_stale_models(folder: Path, written: set[Path]) -> None:
    """Remove the model files an earlier demo left in ``folder`` that this run did not write (a
    method not learned this time, ``cf-dagger``/``cf-logit`` with ``dagger_rounds`` 0): they would
    read as this run's. Files of other names are left alone."""
    for name in (*method_names(), CF_DRIVER, "cf-logit", PLANNER_DRIVER):
        path = folder / f"{name}.json"
        if path not in written and path.is_file():
            path.unlink()


def _run_logged_episode(config: DemoConfig, policy, logger) -> None:
    """One episode in this process, with ``logger`` attached to the episode's controller."""
    ctl = Controller(policy)
    logger.controller = ctl
    spec = load_scenario(config.scenario)
    run_scenario(spec, seed=config.eval_seed, duration_s=config.eval_duration_s, hooks=[ctl, logger])
