"""Files of an evaluation: ``report.md``, ``metrics.json`` and the PNG plots (matplotlib Agg)."""

from __future__ import annotations

import json
import math
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pandas as pd

from analysis.metrics import AggregateMetrics
from analysis.provenance import provenance_markdown
from irl.atomic import write_atomic, write_text_atomic
from irl.domains.merge import ACTION_NAMES, N_ACTIONS


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
            "| A mean speed (ft/s) | W1 speed / acc / d_AC / TTC | held-out LL / step | safety interventions "
            "| flags |")
    sep = "|" + "---|" * 15
    rows = [head, sep]
    for name, a in aggs.items():
        inter = f"{a.safety_interventions} ({_fmt(a.intervention_rate, 3)})" if a.safety_interventions else "0"
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
                  provenance: dict | None = None, left_out: list[str] | tuple[str, ...] = ()):
    """Write report.md, metrics.json and the plots; return their paths. ``provenance``
    (:func:`analysis.provenance.provenance`) goes into both."""
    plots = (
        plot_action_histograms(out / "action_histograms.png", aggs, held),
        plot_gap_acceptance(out / "gap_acceptance.png", by_policy),
        plot_speed_profiles(out / "speed_profiles.png", by_policy),
    )
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
        f"policy); decision step {controller.decision_s} s, actions {'mode' if controller.mode else 'sampled'}, "
        f"safety filter {'off (raw)' if controller.safety_ttc_s is None else f'on (TTC >= {controller.safety_ttc_s} s)'}.",
        "Policy `sumo` is SUMO's own car-following model in role A (not taken over); `uniform` picks actions "
        "uniformly at random.",
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
        "(ft) and TTC to C (s) at the decisions to the held-out demonstrations; `sumo`'s row is the floor. "
        "Baselines `marginal`, `markov`, `bc` are fitted on the training demonstrations (add-one smoothed). "
        "Safety interventions: actions replaced by the safety filter (0 unless it is on).",
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


def _plt():
    # matplotlib (about 0.5 s to import) only when a plot is drawn
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: Path) -> Path:
    write_atomic(path, lambda p: fig.savefig(p, dpi=110, bbox_inches="tight"))
    _plt().close(fig)
    return path


def plot_action_histograms(path: Path, aggs, held) -> Path:
    plt = _plt()
    series = {}
    if held is not None:
        series["demonstrations"] = np.asarray(held.action_counts, float)
    for name, a in aggs.items():
        series[name] = np.asarray(a.action_counts, float)
    fig, ax = plt.subplots(figsize=(8, 4))
    w = 0.8 / max(1, len(series))
    x = np.arange(N_ACTIONS)
    for i, (name, c) in enumerate(series.items()):
        ax.bar(x + i * w - 0.4 + w / 2, c / c.sum() if c.sum() else c, width=w, label=name)
    ax.set_xticks(x, ACTION_NAMES)
    ax.set_ylabel("share of decisions")
    ax.set_title("Action of car A")
    ax.legend(fontsize=8)
    return _save(fig, path)


def plot_gap_acceptance(path: Path, by_policy) -> Path:
    """Share of merges with B ahead of A, by the gap d_AB at take-over (ft)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 4))
    bins = np.array([-np.inf, 0, 50, 100, 150, 200, np.inf])
    labels = ["<0", "0-50", "50-100", "100-150", "150-200", ">200"]
    for name, rs in by_policy.items():
        ct = pd.concat([r.controls for r in rs], ignore_index=True) if rs else pd.DataFrame()
        if ct.empty:
            continue
        ct = ct[ct["merge_frame"] >= 0]
        if ct.empty:
            continue
        k = np.digitize(ct["gap_AB_start_ft"].to_numpy(float), bins[1:-1])
        rate = [float(np.mean(ct["b_ahead"].to_numpy(bool)[k == j])) if np.any(k == j) else np.nan for j in range(len(labels))]
        ax.plot(labels, rate, marker="o", label=name)
    ax.set_xlabel("gap d_AB from A to B at take-over (ft)")
    ax.set_ylabel("share of merges with B ahead of A")
    ax.set_ylim(-0.05, 1.05)
    ax.set_title("Gap acceptance")
    ax.legend(fontsize=8)
    return _save(fig, path)


def plot_speed_profiles(path: Path, by_policy) -> Path:
    """Mean speed of A against time since take-over."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 4))
    for name, rs in by_policy.items():
        sp = pd.concat([r.speed_profiles for r in rs], ignore_index=True) if rs else pd.DataFrame()
        if sp.empty:
            continue
        g = sp.assign(t=np.round(sp["t_s"], 1)).groupby("t")["v_ft_s"]
        m = g.mean()
        n = g.size()
        m = m[n >= 2] if (n >= 2).any() else m
        ax.plot(m.index, m.to_numpy(), label=name)
    ax.set_xlabel("time since take-over (s)")
    ax.set_ylabel("speed of A (ft/s)")
    ax.set_title("Speed profiles of A")
    ax.legend(fontsize=8)
    return _save(fig, path)
