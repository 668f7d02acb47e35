"""``merge-irl learn-driver``: a planning driver learned from demonstrations alone.

Demonstrations are merge encounter tables (``merge-irl generate`` / ``merge-irl encounters``
output, with ``v_A`` and the vehicle lengths) or folders of real car-following pair CSVs (the
layout of ``analysis.calibration.pairs``: C the recorded leader, no B). Two criteria
(:data:`FITS`):

* ``replay`` (the default when every source is a pair folder): the reward's weights and gap shape
  are chosen by what the driver does when it drives, replaying the training pairs from their
  recorded initial states (:func:`irl.planning.replay_fit.fit_by_replay`), then its
  temperature by the training likelihood (:func:`~irl.planning.replay_fit.fit_temperature`).
  With ``holdout``, followers are split as ``merge-irl calibrate fit --holdout`` splits them
  (:func:`analysis.calibration.pairs.split_by_follower`, same seed: the same followers), and the
  held-out followers are scored beside IDM with SUMO's defaults (:func:`heldout_report`).
* ``likelihood`` (the default for encounter tables): the planner's settings chosen by held-out
  likelihood on a split of the groups, its weights by maximum likelihood on all of them
  (:func:`irl.planning.driver.learn_planning_driver`). Several sources are learned
  from together, their encounters and pairs kept apart as groups.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from analysis.calibration.driver_eval import replay_pairs
from irl.domains.merge.mdp import DEFAULT_DECISION_STEP_S, read_encounters
from irl.errors import DemonstrationError
from irl.planning.decisions import PlanningDecisions, encounter_decisions, pair_decisions
from irl.planning.driver import PlanningDriver, learn_planning_driver, shape_of
from irl.planning.model import LIKELIHOOD_ROAD_MODEL, PlannerConfig
from irl.planning.replay_fit import ReplayFitConfig, fit_by_replay, fit_temperature
from merge_irl.provenance import provenance
from merge_irl.tables import is_parquet_dataset
from merge_irl.units import FT_PER_M

#: The criteria a driver can be fitted by (module docstring); ``auto``: replay when every source
#: is a folder of pairs, else likelihood.
FITS = ("auto", "replay", "likelihood")
#: A bumper gap (m) closer than which a follower counts as close (the share reported).
CLOSE_GAP_M = 2.0


def pair_frames(pairs) -> tuple[list[pd.DataFrame], list[str]]:
    """Car-following pairs (:class:`analysis.calibration.pairs.CarFollowingPair`, SI units) as
    the planning driver's pair tables (ft, ft/s; :data:`irl.planning.decisions.PAIR_COLUMNS`)
    and their followers (the groups)."""
    frames = [pd.DataFrame({"t": p.t, "x_follower": p.x_follower * FT_PER_M, "v_follower": p.v_follower * FT_PER_M,
                            "x_leader": p.x_leader * FT_PER_M, "v_leader": p.v_leader * FT_PER_M,
                            "leader_length": p.leader_length * FT_PER_M}) for p in pairs]
    return frames, [p.group for p in pairs]


def load_driver_demos(paths: Sequence[str | os.PathLike], *,
                      decision_step_s: float = DEFAULT_DECISION_STEP_S) -> PlanningDecisions:
    """The decisions of every source in ``paths``: an encounter table (``.parquet``/``.csv``) or
    a folder of pair CSVs (a ``train/`` subfolder is read as ``analysis.calibration`` reads it).

    Raises:
        DemonstrationError: no source, a missing path, or a source without decisions (named).
        SpecError: a malformed pair file (file, line and column named).
    """
    from analysis.calibration.pairs import load_pairs

    if not paths:
        raise DemonstrationError("learn-driver: no demonstrations given (--demos PATH)")
    parts = []
    for p in map(Path, paths):
        if not p.exists():
            raise DemonstrationError(f"{p}: no such file or directory")
        if p.is_dir() and not is_parquet_dataset(p):
            frames, groups = pair_frames(load_pairs(p))
            parts.append(pair_decisions(frames, decision_step_s, groups=groups, where=str(p)))
        else:
            parts.append(encounter_decisions(read_encounters(p), decision_step_s, where=str(p)))
    return PlanningDecisions.concat(parts)


def resolve_fit(fit: str, paths: Sequence[str | os.PathLike]) -> str:
    """``"replay"`` or ``"likelihood"``: ``fit``, or for ``"auto"`` replay when every source is a
    folder of pairs.

    Raises:
        DemonstrationError: an unknown ``fit``.
    """
    if fit not in FITS:
        raise DemonstrationError(f"learn-driver: --fit must be one of {FITS}, got {fit!r}")
    if fit != "auto":
        return fit
    pair_dirs = [p for p in paths if Path(p).is_dir() and not is_parquet_dataset(p)]
    return "replay" if paths and len(pair_dirs) == len(paths) else "likelihood"


def learn_driver(paths: Sequence[str | os.PathLike], out: str | os.PathLike | None = None, *, seed: int = 0,
                 decision_step_s: float = DEFAULT_DECISION_STEP_S, select: bool = True,
                 log: Callable[[str], None] = lambda s: None) -> PlanningDriver:
    """Learn a planning driver on the demonstrations of ``paths`` (:func:`load_driver_demos`)
    and, with ``out``, write it (format ``merge-irl-planner/1``) with the provenance of its inputs
    in ``info["provenance"]``. ``select``: choose the planner's settings by held-out likelihood
    (else :class:`~irl.planning.model.PlannerConfig`'s defaults). ``log`` receives
    one line per selection trial.

    Raises:
        DemonstrationError, SpecError: bad demonstrations (see :func:`load_driver_demos`).
        OSError: ``out`` cannot be written.
    """
    decisions = load_driver_demos(paths, decision_step_s=decision_step_s)
    log(f"{decisions.n} decisions in {len(set(decisions.groups.tolist()))} encounters/pairs")
    selection = "heldout" if select else PlannerConfig(decision_step_s=decisions.decision_step_s,
                                                        road_model=LIKELIHOOD_ROAD_MODEL)
    driver = learn_planning_driver(decisions, seed=seed, selection=selection, log=log)
    driver.info["stopped"] = "converged" if driver.converged else f"iteration cap ({driver.info.get('n_iter')} iterations)"
    vals = [t["val_ll"] for t in driver.info.get("selection", []) if math.isfinite(t["val_ll"])]
    _flag_heldout(driver.info, max(vals) if vals else None, "the selection's validation followers")
    inputs = {("demos" if len(paths) == 1 else f"demos{i}"): p for i, p in enumerate(paths, start=1)}
    driver.info["provenance"] = provenance(inputs)
    driver.info["demos"] = [str(p) for p in paths]
    if out is not None:
        driver.save(out)
    return driver


def _flag_heldout(info: dict, ll_per_decision: float | None, what: str) -> None:
    """``info["flags"]`` and ``info["flagged_heldout"]``: ``evaluate``'s check of a held-out
    likelihood per decision (:func:`analysis.evaluation.outcome.heldout_flags`: below uniform
    actions' is flagged); ``what`` names the held-out data."""
    from analysis.evaluation.outcome import heldout_flags

    flags = heldout_flags(None if ll_per_decision is None else (math.nan, ll_per_decision))
    info["flags"] = list(flags)
    if flags:
        info["flagged_heldout"] = {"data": what, "ll_per_decision": ll_per_decision}


def flag_lines(driver: PlanningDriver) -> list[str]:
    """One warning line per reason not to trust ``driver`` (empty: none): a fit that did not
    converge (``info["stopped"]`` says why it stopped) and a held-out likelihood below uniform
    actions' (``info["flags"]``, as ``evaluate`` flags a policy)."""
    from analysis.evaluation.outcome import UNIFORM_LL_PER_STEP

    out = []
    if not driver.converged:
        out.append(f"WARNING: the fit did not converge (stopped: {driver.info.get('stopped', 'unknown')})")
    h = driver.info.get("flagged_heldout")
    if driver.info.get("flags") and h:
        out.append(f"WARNING: flagged ({', '.join(driver.info['flags'])}): the held-out log-likelihood per decision "
                   f"on {h['data']}, {h['ll_per_decision']:.3f}, is below uniform actions' ({UNIFORM_LL_PER_STEP:.3f}): "
                   "the driver predicts them worse than chance; do not rank or deploy it without checking")
    return out


def heldout_report(driver: PlanningDriver, pairs, *, decision_step_s: float) -> dict[str, float]:
    """The driver on held-out ``pairs`` (:class:`analysis.calibration.pairs.CarFollowingPair`)
    beside IDM with SUMO's default parameters on the same pairs (numpy replica): median and mean
    spacing RMSE (m), collisions, the share of pairs closer than :data:`CLOSE_GAP_M` (driver,
    recorded), and the held-out likelihood per decision of the paper actions.

    Raises:
        DemonstrationError: no pairs.
    """
    from analysis.calibration.driver_eval import evaluate_act

    if not pairs:
        raise DemonstrationError("held-out report: no pairs")
    ev = evaluate_act(driver.act, driver.decision_step_s, pairs)
    frames, groups = pair_frames(pairs)
    dec = pair_decisions(frames, decision_step_s, groups=groups)
    recorded_close = float(np.mean([float(np.min(p.spacing)) < CLOSE_GAP_M for p in pairs]))
    return {"pairs": len(pairs), "median_rmse_m": float(np.median(ev.rmse_m)), "mean_rmse_m": float(np.mean(ev.rmse_m)),
            "idm_defaults_median_rmse_m": float(np.median(ev.default_rmse_m)),
            "idm_defaults_mean_rmse_m": float(np.mean(ev.default_rmse_m)),
            "collisions": int(ev.collided.sum()), "close_share": float(np.mean(ev.min_gap_m < CLOSE_GAP_M)),
            "recorded_close_share": recorded_close, "ll_per_decision": driver.heldout_ll_per_decision(dec)}


def learn_driver_by_replay(pair_dirs: Sequence[str | os.PathLike], out: str | os.PathLike | None = None, *,
                           holdout: float = 0.0, seed: int = 0, decision_step_s: float = DEFAULT_DECISION_STEP_S,
                           config: ReplayFitConfig | None = None,
                           log: Callable[[str], None] = lambda s: None) -> PlanningDriver:
    """A planning driver fitted by replaying the pairs of ``pair_dirs`` (module docstring) and,
    with ``out``, written with its provenance. ``config``: the fit's settings (default
    :class:`~irl.planning.replay_fit.ReplayFitConfig`), its planner at ``decision_step_s``. ``holdout``: the fraction of followers held out
    (0: none), split with ``seed``; their report is in ``info["heldout"]``.

    Raises:
        DemonstrationError: a source that is not a folder of pairs, or no pairs.
        SpecError: a malformed pair file, or a bad ``holdout``.
        OSError: ``out`` cannot be written.
    """
    from analysis.calibration.pairs import load_pairs, split_by_follower

    pairs: list = []
    for p in map(Path, pair_dirs):
        if not p.is_dir():
            raise DemonstrationError(f"{p}: --fit replay needs folders of car-following pair CSVs; an encounter "
                                     "table is fitted with --fit likelihood")
        pairs.extend(load_pairs(p))
    train, test = split_by_follower(pairs, holdout, seed) if holdout else (tuple(pairs), ())
    cfg = config or ReplayFitConfig()
    cfg = replace(cfg, planner=replace(cfg.planner, decision_step_s=decision_step_s))
    frames, groups = pair_frames(train)
    dec = pair_decisions(frames, decision_step_s, groups=groups)
    log(f"{len(train)} training pairs of {len({p.group for p in train})} followers ({dec.n} decisions)"
        + (f", {len(test)} held-out pairs of {len({p.group for p in test})} followers" if test else ""))
    fit = fit_by_replay(replay_pairs(train), shape_of(dec), dec.action_acc_ft_s2(), cfg, log=log)
    stopped = "converged" if fit.converged else f"budget ({fit.n_evals} replays of max_evals {cfg.max_evals})"
    log(f"replay fit: {fit.objective:.3f} m (from {fit.start_objective:.3f} m) after {fit.n_evals} replays, "
        f"{fit.seconds:.0f} s{'' if fit.converged else ' (stopped at its budget: not converged)'}")
    driver, ll = fit_temperature(fit.driver, dec)
    log(f"temperature {driver.config.temperature:.3g}: training LL {ll:.4f} per decision")
    info: dict = {**driver.info, "n_decisions": dec.n, "seed": seed, "holdout": holdout,
                  "train_pairs": len(train), "replay_params": fit.params,
                  "train_median_rmse_m": float(np.median(fit.result.rmse_m)),
                  "train_collisions": int(fit.result.collided.sum()), "stopped": stopped}
    if test:
        info["heldout"] = heldout_report(driver, test, decision_step_s=decision_step_s)
        h = info["heldout"]
        log(f"held out ({h['pairs']} pairs): median RMSE {h['median_rmse_m']:.2f} m (IDM, SUMO's defaults "
            f"{h['idm_defaults_median_rmse_m']:.2f} m), mean {h['mean_rmse_m']:.2f} m "
            f"({h['idm_defaults_mean_rmse_m']:.2f}), collisions {h['collisions']}, closer than {CLOSE_GAP_M:g} m "
            f"{100 * h['close_share']:.0f} % (recorded {100 * h['recorded_close_share']:.0f} %), LL "
            f"{h['ll_per_decision']:.3f} per decision")
    _flag_heldout(info, info["heldout"]["ll_per_decision"] if test else None, "the held-out pairs")
    info["provenance"] = provenance({("demos" if len(pair_dirs) == 1 else f"demos{i}"): p
                                     for i, p in enumerate(pair_dirs, start=1)})
    info["demos"] = [str(p) for p in pair_dirs]
    driver = replace(driver, loglik=ll * dec.n, converged=fit.converged, info=info)
    if out is not None:
        driver.save(out)
    return driver
