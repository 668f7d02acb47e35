"""Files of an evaluation: ``report.md``, ``metrics.json`` and the PNG plots (matplotlib Agg)."""

from __future__ import annotations

import json
import math
from dataclasses import asdict
from pathlib import Path

import numpy as np

from analysis.evaluation.aggregate import AggregateMetrics
from merge_irl.provenance import provenance_markdown
from analysis.evaluation.plots import write_plots
from merge_irl.atomic import write_text_atomic
from irl.domains.merge.actions import ACTION_NAMES, N_ACTIONS


def _fmt(x, nd=2) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "inf" if isinstance(x, float) and math.isinf(x) and x > 0 else "-"
    return f"{x:.{nd}f}"


def _pm(t, nd=2) -> str:
    m, s = t
    if not math.isfinite(m):
        return "-"
    return f"{m:.{nd}f} ± {s:.{nd}f}" if math.isfinite(s) else f"{m:.{nd}f}"


def _ci(a: AggregateMetrics) -> str:
    lo, hi = a.a_collision_ci95
    if not math.isfinite(a.a_collision_rate):
        return "-"
    return f"{a.a_collisions}/{a.n_controls} [{lo:.3f}, {hi:.3f}]"


def _w1(a: AggregateMetrics) -> str:
    xs = (a.w1_speed_A_ft_s, a.w1_acc_A_ft_s2, a.w1_d_AC_ft, a.w1_ttc_s)
    return " / ".join(_fmt(x, 1) for x in xs)


def report_table(aggs: dict[str, AggregateMetrics]) -> str:
    """The markdown table, one row per policy (flagged models marked ``FLAGGED``)."""
    head = ("| policy | episodes | As controlled | merges | collisions (all / A) | A collisions / As [95 % CI] "
            "| emergency brakings (near / all) | min TTC (s) | B merged ahead of A | A travel time (s) "
            "| A mean speed (ft/s) | W1 speed / acc / d_AC / TTC | held-out LL / step | interventions (filter / need) "
            "| flags |")
    sep = "|" + "---|" * 15
    rows = [head, sep]
    for name, a in aggs.items():
        inter = f"{a.safety_interventions} ({_fmt(a.intervention_rate, 3)})" if a.safety_interventions else "0"
        inter += f" / {a.need_brakes}"
        flags = ("FLAGGED: " + ", ".join(a.flags)) if a.flags else ""
        rows.append(
            f"| {name} | {a.n_episodes} | {a.n_controls} | {a.n_merges} | {a.collisions} / {a.a_collisions} "
            f"| {_ci(a)} | {a.emergency_brakings} / {a.emergency_brakings_all} | {_fmt(a.min_ttc_s)} "
            f"| {_pm(a.b_ahead_rate)} | {_pm(a.travel_time_s, 1)} | {_pm(a.mean_speed_A_ft_s, 1)} "
            f"| {_w1(a)} | {_fmt(a.heldout_loglik_per_step, 3)} | {inter} | {flags} |"
        )
    return "\n".join(rows)


def flag_lines(aggs: dict[str, AggregateMetrics]) -> list[str]:
    """One warning line per flagged model (empty: none)."""
    return [f"WARNING: model {name} is flagged ({', '.join(a.flags)}): its fit did not reach a usable "
            "maximum; do not rank or deploy it without checking" for name, a in aggs.items() if a.flags]


def metrics_to_json(obj) -> str:
    """JSON text with NaN/inf written as null."""
    def clean(x):
        if isinstance(x, float):
            return x if math.isfinite(x) else None
        if isinstance(x, dict):
            return {str(k): clean(v) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [clean(v) for v in x]
        if isinstance(x, (np.integer,)):
            return int(x)
        if isinstance(x, (np.floating,)):
            return clean(float(x))
        if isinstance(x, np.bool_):
            return bool(x)
        return x
    return json.dumps(clean(obj), indent=1)


def write_outputs(out: Path, aggs, by_policy, held, *, scenario, seed, episodes, duration_s, controller, metrics,
                  provenance: dict | None = None, speed_limit_ft_s: float | None = None,
                  left_out: list[str] | tuple[str, ...] = ()):
    """Write report.md, metrics.json and the plots (:mod:`analysis.evaluation.plots`); return their
    paths. ``provenance`` (:func:`merge_irl.provenance.provenance`) goes into both; ``left_out``
    names the baselines that could not be fitted (no training demonstrations)."""
    plots = write_plots(out, aggs, by_policy, held, speed_limit_ft_s=speed_limit_ft_s)
    payload = {
        "format": "merge-irl-evaluation/1",
        "scenario": scenario, "seed": seed, "episodes": episodes, "duration_s": duration_s,
        "controller": asdict(controller), "metrics_config": asdict(metrics),
        "demos": {"source": held.source, "action_counts": held.action_counts.tolist(),
                  "n_steps": int(len(held.encounters))} if held is not None else None,
        "policies": {
            name: {"aggregate": a.to_dict(), "episodes": [r.metrics.to_dict() for r in by_policy[name]]}
            for name, a in aggs.items()
        },
    }
    if provenance is not None:
        payload["provenance"] = provenance
    mj = write_text_atomic(out / "metrics.json", metrics_to_json(payload))
    lines = [
        f"# Closed-loop evaluation: {scenario}",
        "",
        f"{episodes} episode(s) per policy, seeds {seed}..{seed + episodes - 1} (the same traffic for every "
        f"policy); decision step {controller.decision_step_s} s, actions {'mode' if controller.mode else 'sampled'}, "
        f"safety filter {'off (raw)' if controller.safety_ttc_s is None else f'on (TTC >= {controller.safety_ttc_s} s)'}; "
        + ("actuation physical: every action at the driver's own acceleration, capped at A's emergency deceleration."
           if controller.high_brake == "mean" else
           "actuation `need`: High Brake harder when the simulator's ground truth (A's true leader and its "
           "acceleration) says A needs it; not a learned driver's doing (column interventions, need)."),
        "Policy `sumo` is SUMO's own car-following model in role A (not taken over); `uniform` picks actions "
        "uniformly at random; `sumo-in-lane` (if run) is `sumo` with A's lane changes off while observed, as "
        "for every commanded driver; `idm` (if run) is the Intelligent Driver Model with the scenario's car "
        "parameters driving A through the controller (deterministic: no held-out LL).",
        "",
        report_table(aggs),
        "",
        "Columns: collisions in the whole run / control episodes ended by A colliding; emergency brakings "
        f"(decel > {metrics.emergency_decel_m_s2} m/s^2) by A, B and A's follower while A is controlled / by "
        "every vehicle; min TTC over A->leader and follower->A while controlled; B merged ahead of A = share "
        "of merges (mean ± std over episodes); JS divergence (base 2) between A's action distribution and the "
        "demonstrations'; held-out LL = mean log pi(a|s) per held-out demonstration step (state-conditional; "
        "markov given the previous action). A collisions / As: control episodes ended by A colliding, with the "
        "Wilson 95 % interval. W1: Wasserstein-1 distances of A's speed (ft/s), acceleration (ft/s^2), d_AC "
        "(ft) and TTC to C (s) at the decisions to the held-out demonstrations; `sumo`'s row is the floor "
        "(`sumo-in-lane`'s the floor of drivers that act on acceleration alone). "
        "Baselines `marginal`, `markov`, `bc` (when run) are fitted on the training demonstrations (add-one "
        "smoothed). "
        "Interventions: actions replaced by the safety filter (0 unless it is on) / High Brakes the `need` "
        "actuation made harder than the driver's own (0 under the physical actuation).",
        "",
        *flag_lines(aggs),
        *([f"Left out: {', '.join(left_out)} (no training demonstrations given)."] if left_out else []),
        "",
        "Release reasons (all episodes):",
        "",
    ]
    for name, a in aggs.items():
        rs = ", ".join(f"{k} {v}" for k, v in sorted(a.release_reasons.items())) or "none"
        lines.append(f"- {name}: {rs}")
    lines += ["", "Action distribution (share of decisions):", "",
              "| policy | " + " | ".join(ACTION_NAMES) + " |", "|---|" + "---|" * N_ACTIONS]
    if held is not None:
        c = held.action_counts / max(1, held.action_counts.sum())
        lines.append("| demonstrations | " + " | ".join(f"{x:.3f}" for x in c) + " |")
    for name, a in aggs.items():
        c = np.asarray(a.action_counts, float)
        c = c / c.sum() if c.sum() else c
        lines.append(f"| {name} | " + " | ".join(f"{x:.3f}" for x in c) + " |")
    lines += ["", "Plots: " + ", ".join(f"[{p.name}]({p.name})" for p in plots), ""]
    if provenance is not None:
        lines += [provenance_markdown(provenance), ""]
    rm = write_text_atomic(out / "report.md", "\n".join(lines))
    return rm, mj, plots
