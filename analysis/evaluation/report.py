"""Files of an evaluation: ``report.md``, ``metrics.json`` and the PNG plots (matplotlib Agg).

``report.md`` has two tables per evaluation, one row per policy: :data:`COLUMNS` (safety and
traffic, :func:`report_table`) and :data:`HUMAN_COLUMNS` (human likeness beside the held-out
demonstrations, :func:`human_table`), each with a legend generated from its columns."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from analysis.evaluation.aggregate import AggregateMetrics
from analysis.evaluation.human_likeness import CLOSE_GAP_M, DemoCloseness
from analysis.evaluation.intervals import rate_ci95
from analysis.evaluation.plots import write_plots
from analysis.evaluation.recorded import W1_KEYS, RecordedComparison, RecordedDrivers
from irl.domains.merge.actions import ACTION_NAMES, N_ACTIONS
from merge_irl.atomic import write_text_atomic
from merge_irl.provenance import provenance_markdown
from sim.closed_loop.records import COLLISION_KINDS


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


def _interventions(a: AggregateMetrics) -> str:
    inter = f"{a.safety_interventions} ({_fmt(a.intervention_rate, 3)})" if a.safety_interventions else "0"
    return inter + f" / {a.need_brakes}"


@dataclass(frozen=True)
class Column:
    """One column of :func:`report_table`: its header, its legend (``{decel}``: the emergency
    deceleration threshold, ``{tol}``: its tolerance, both m/s^2) and its cell for one policy."""

    header: str
    legend: str
    cell: Callable[[str, AggregateMetrics], str]


#: The columns of the report table, in order; the legend under the table is generated from
#: them (:func:`column_legend`), so it describes exactly the columns shown.
COLUMNS: tuple[Column, ...] = (
    Column("policy", "the driver of A", lambda name, a: name),
    Column("episodes", "episodes (seeds) run", lambda name, a: str(a.n_episodes)),
    Column("As controlled", "control episodes: lag cars A taken over", lambda name, a: str(a.n_controls)),
    Column("merges", "merges of B completed while its A was controlled", lambda name, a: str(a.n_merges)),
    Column("collisions (all / A)",
           "distinct colliding pairs (collider, victim) in the whole run, every vehicle / those of them that "
           "ended a control episode of A (a pair seen again in a later take-over of the same A counts once, "
           "so A <= all)",
           lambda name, a: f"{a.collisions} / {a.a_collisions}"),
    Column("A collisions / As [95 % CI]",
           "A's collision pairs over the As controlled, with the Wilson 95 % interval", lambda name, a: _ci(a)),
    Column("emergency brakings (near / all)",
           "brakings strictly beyond {decel} m/s^2 (acceleration below -({decel} + {tol}) m/s^2) by A, B and A's "
           "follower while A is controlled / by every vehicle",
           lambda name, a: f"{a.emergency_brakings} / {a.emergency_brakings_all}"),
    Column("emergency brakings by A / B / A's follower",
           "the near ones by role (a car in two roles counted as the first of A, B, follower: they add up to near)",
           lambda name, a: _by_role(a)),
    Column("min TTC (s)", "smallest time-to-collision over A->leader and follower->A while controlled",
           lambda name, a: _fmt(a.min_ttc_s)),
    Column("B merged ahead of A", "share of the merges (mean ± std over episodes)",
           lambda name, a: _pm(a.b_ahead_rate)),
    Column("A travel time (s)", "time A takes to cross the section (mean ± std over episodes)",
           lambda name, a: _pm(a.travel_time_s, 1)),
    Column("A mean speed (ft/s)", "A's mean speed while controlled (mean ± std over episodes)",
           lambda name, a: _pm(a.mean_speed_A_ft_s, 1)),
    Column("W1 speed / acc / d_AC / TTC",
           "Wasserstein-1 distances of A's speed (ft/s), acceleration (ft/s^2), d_AC (ft) and TTC to C (s) at "
           "the decisions to the held-out demonstrations, `sumo`'s row the floor (`sumo-in-lane`'s the "
           "floor of drivers that act on acceleration alone)", lambda name, a: _w1(a)),
    Column("held-out LL / step",
           "mean log pi(a|s) per held-out demonstration step (state-conditional, markov given the previous "
           "action)", lambda name, a: _fmt(a.heldout_loglik_per_step, 3)),
    Column("interventions (filter / need)",
           "actions replaced by the safety filter (0 unless it is on) / High Brakes the `need` actuation made "
           "harder than the driver's own (0 under the physical actuation)", lambda name, a: _interventions(a)),
    Column("flags", "what the model's fit reported (FLAGGED: do not rank or deploy it without checking)",
           lambda name, a: ("FLAGGED: " + ", ".join(a.flags)) if a.flags else ""),
)


def _by_role(a: AggregateMetrics) -> str:
    """``A / B / follower`` emergency brakings."""
    return f"{a.emergency_brakings_A} / {a.emergency_brakings_B} / {a.emergency_brakings_follower}"


def _per_a(k: int, n: int, rate: float, ci: tuple[float, float]) -> str:
    """``k/n = rate [low, high]`` ("-" when ``n`` is 0)."""
    if not math.isfinite(rate):
        return "-"
    return f"{k}/{n} = {rate:.3f} [{ci[0]:.3f}, {ci[1]:.3f}]"


#: The columns of the human-likeness table (:func:`human_table`); ``{gap}`` in a header or legend
#: is the close-to-C threshold (m), ``{decel}`` the emergency deceleration (m/s^2).
HUMAN_COLUMNS: tuple[Column, ...] = (
    Column("policy", "the driver of A (`demonstrations`: the held-out encounters)", lambda name, a: name),
    Column("As controlled", "control episodes (`demonstrations`: encounters)", lambda name, a: str(a.n_controls)),
    Column("emergency brakings near A per A [95 % CI]",
           "brakings strictly beyond {decel} m/s^2 (below -({decel} + {tol}) m/s^2) by A, B and A's follower while "
           "A is controlled, per controlled A, with the exact Poisson 95 % interval (events, not As: one A can "
           "cause several)",
           lambda name, a: _per_a(a.emergency_brakings, a.n_controls, a.emergency_braking_rate,
                                  a.emergency_braking_ci95)),
    Column("emergency brakings by A / B / A's follower", "those brakings by role",
           lambda name, a: _by_role(a)),
    Column("A into C / A into B",
           "of A's collision pairs, those where A ran into its lead car C / into the merging car B",
           lambda name, a: f"{a.a_into_c} / {a.a_into_b}"),
    Column("As within {gap} m of C [95 % CI]",
           "share of the controlled As whose bumper gap to their lead car C (the nearest merge-lane car ahead "
           "other than B) fell below {gap} m while controlled, with the Wilson 95 % interval; "
           "`demonstrations`: the held-out encounters whose A came that close to C (d_AC - len_C)",
           lambda name, a: _per_a(a.close_to_c, a.n_controls, a.close_to_c_rate, a.close_to_c_ci95)),
    Column("W1 acc (m/s^2)",
           "Wasserstein-1 distance of A's acceleration per 0.1 s frame while controlled (the forward difference "
           "of its speed over one frame) to the held-out demonstrations' `acc_A`", lambda name, a: _fmt(a.w1_acc_A_m_s2)),
    Column("W1 jerk (m/s^3)",
           "Wasserstein-1 distance of A's jerk per 0.1 s frame (the forward difference of that acceleration over "
           "one frame) to the demonstrations' (of `acc_A` over consecutive frames of an encounter)",
           lambda name, a: _fmt(a.w1_jerk_A_m_s3)),
)


def report_table(aggs: dict[str, AggregateMetrics], columns: tuple[Column, ...] = COLUMNS, *,
                 close_gap_m: float = CLOSE_GAP_M) -> str:
    """The markdown table, one row per policy (flagged models marked ``FLAGGED``); ``{gap}`` in a
    header is ``close_gap_m``."""
    rows = ["| " + " | ".join(_header(c, close_gap_m) for c in columns) + " |", "|" + "---|" * len(columns)]
    for name, a in aggs.items():
        rows.append("| " + " | ".join(c.cell(name, a) for c in columns) + " |")
    return "\n".join(rows)


def human_table(aggs: dict[str, AggregateMetrics], demos: DemoCloseness | None = None, *,
                close_gap_m: float = CLOSE_GAP_M, recorded: RecordedComparison | None = None) -> str:
    """The human-likeness table (:data:`HUMAN_COLUMNS`), one row per policy, and first rows
    ``demonstrations`` with the held-out encounters' share within ``close_gap_m`` of C when
    ``demos`` is given (its other cells ``-``) and ``recorded drivers`` when ``recorded`` is
    given: then the table has the columns of :func:`human_columns` and the recorded row its
    pairs, its share of pairs within the gap and its own summary (its other cells ``-``)."""
    columns = human_columns(recorded)
    table = report_table(aggs, columns, close_gap_m=close_gap_m)
    lines = table.split("\n")
    first = []
    pad = ["-"] * (len(columns) - len(HUMAN_COLUMNS))
    if demos is not None:
        first.append(["demonstrations", str(demos.n_encounters), "-", "-", "-",
                      _per_a(demos.n_close, demos.n_encounters, demos.rate, demos.ci95), "-", "-", *pad])
    if recorded is not None:
        first.append(_recorded_cells(recorded.recorded))
    return "\n".join([*lines[:2], *("| " + " | ".join(c) + " |" for c in first), *lines[2:]])


def _recorded_cells(rec: RecordedDrivers) -> list[str]:
    """The ``recorded drivers`` row of :func:`human_table` (the columns of :func:`human_columns`)."""
    rate, lo, hi = rec.close_rate
    return ["recorded drivers", str(rec.n_pairs), "-", "-", "-", _per_a(rec.n_close, rec.n_pairs, rate, (lo, hi)),
            "-", "-", "-", _summary(rec.summary)]


def _summary(summary: dict[str, float] | None) -> str:
    """``mean abs acc / median gap / median headway`` (``-`` where unknown)."""
    if summary is None:
        return "-"
    return " / ".join(_fmt(summary[k]) for k in ("mean_abs_acc_m_s2", "median_gap_m", "median_headway_s"))


def human_columns(recorded: RecordedComparison | None = None) -> tuple[Column, ...]:
    """:data:`HUMAN_COLUMNS`, and with ``recorded`` two more: each driver's Wasserstein-1
    distances to the recorded drivers (:mod:`analysis.evaluation.recorded`) and its own mean
    absolute acceleration, median gap and median time headway."""
    if recorded is None:
        return HUMAN_COLUMNS
    drivers = recorded.drivers

    def w1(name: str, a: AggregateMetrics) -> str:
        d = drivers.get(name)
        return " / ".join(_fmt(d.w1[k]) for k in W1_KEYS) if d is not None else "-"

    def own(name: str, a: AggregateMetrics) -> str:
        d = drivers.get(name)
        return _summary(d.summary if d is not None else None)

    step = f"{recorded.recorded.decision_step_s:g}"
    return (*HUMAN_COLUMNS,
            Column("W1 to recorded acc / jerk / gap / headway",
                   "Wasserstein-1 distances to the `recorded drivers` (the followers of the real pairs, --pairs) of "
                   "A's acceleration (m/s^2) and jerk (m/s^3) per 0.1 s frame while controlled, and of its bumper "
                   f"gap to C (m) and time headway (gap / own speed, s) at its decisions; the recorded side per "
                   f"frame and every {step} s (the decision step) likewise", w1),
            Column("mean abs acc / median gap / median headway",
                   "the same samples' mean absolute acceleration (m/s^2), median gap (m) and median time headway "
                   "(s); `recorded drivers`: the recorded followers'", own))


def _header(c: Column, close_gap_m: float) -> str:
    return c.header.format(gap=f"{close_gap_m:g}")


def column_legend(columns: tuple[Column, ...] = COLUMNS, *, emergency_decel_m_s2: float = 4.5,
                  close_gap_m: float = CLOSE_GAP_M, emergency_tolerance_m_s2: float = 0.05) -> str:
    """The legend of :func:`report_table` with the same ``columns``: one entry per column, in order."""
    return "Columns: " + "; ".join(
        f"{_header(c, close_gap_m)} = "
        f"{c.legend.format(decel=f'{emergency_decel_m_s2:g}', tol=f'{emergency_tolerance_m_s2:g}', gap=f'{close_gap_m:g}')}"
        for c in columns) + "."


def emergency_line(metrics) -> str:
    """What report.md counts as an emergency braking (``metrics``: the
    :class:`~analysis.evaluation.metrics.MetricsConfig`)."""
    d, tol = metrics.emergency_decel_m_s2, metrics.emergency_tolerance_m_s2
    return (f"Emergency braking: a run of consecutive 0.1 s frames of one car with acceleration below -({d:g} + "
            f"{tol:g}) m/s^2, i.e. strictly beyond {d:g} m/s^2 by more than the tolerance {tol:g} m/s^2 (a car "
            f"braking at exactly {d:g} m/s^2, SUMO's normal maximum, is not counted); near A: by A, B or A's "
            "follower while A is controlled, counted by role.")


def collision_bound_line(aggs: dict[str, AggregateMetrics]) -> str:
    """How little the episodes can bound, said as the hypothetical it is: the Wilson 95 % upper
    bound of the A collision rate a policy *would* have with 0 A collisions in the fewest As any
    policy had (and the rule of three, 3 / n, Hanley & Lippman-Hand 1983), then which policies
    here had 0 A collisions and which had some (those are bounded by their own interval, not by
    this); "" when no A was controlled."""
    ns = [a.n_controls for a in aggs.values() if a.n_controls > 0]
    if not ns:
        return ""
    n = min(ns)
    episodes = max(a.n_episodes for a in aggs.values())
    _, _, high = rate_ci95(0, n)
    line = (f"What {episodes} episode(s) can show at best (a hypothetical, no policy's result): a policy with 0 A "
            f"collisions in {n} As (the fewest As of any policy here) would bound its A collision rate only below "
            f"{high:.1%} (Wilson 95 % upper bound; rule of three 3/{n} = {3 / n:.1%}); more episodes (--episodes) "
            "bound it tighter.")
    zero = [f"{name} 0/{a.n_controls} (below {rate_ci95(0, a.n_controls)[2]:.1%})"
            for name, a in aggs.items() if a.n_controls > 0 and a.a_collisions == 0]
    some = [f"{name} {a.a_collisions}/{a.n_controls}" for name, a in aggs.items() if a.a_collisions > 0]
    if zero:
        line += f" With 0 A collisions here: {', '.join(zero)}."
    if some:
        line += (f" With A collisions ({', '.join(some)}) a policy is bounded by its own interval in column "
                 "'A collisions / As [95 % CI]', not by this.")
    return line


def collision_count_lines(aggs: dict[str, AggregateMetrics]) -> list[str]:
    """How the collision counts of the report relate, one line per policy with any: the A
    collisions (distinct pairs, the count of the tables) by who hit whom, the control episodes they
    ended (release reason ``collision``; a pair ends several when a later take-over of the same A
    ends at once on it), and the whole run's colliding pairs; [] when no policy had a collision."""
    out = []
    for name, a in aggs.items():
        releases = a.release_reasons.get("collision", 0)
        if not (a.collisions or a.a_collisions or releases):
            continue
        kinds = " + ".join(f"{v} {k}" for k, v in sorted(a.a_collision_kinds.items(), key=_kind_order) if v)
        line = f"- {name}: {a.a_collisions} A collision(s) (distinct colliding pairs with A; the tables' count)"
        if kinds and sum(a.a_collision_kinds.values()) == a.a_collisions:
            line += f" = {kinds}"
        repeat = releases - a.a_collisions
        line += f"; they ended {releases} control episode(s) (release reason collision)"
        if repeat > 0:
            line += (f" = {a.a_collisions} + {repeat} later take-over(s) of the same A that ended at once on a pair "
                     "already counted (SUMO keeps colliding cars overlapping)")
        other = a.collisions - a.a_collisions
        line += (f"; the whole run: {a.collisions} distinct colliding pair(s) = {a.a_collisions} with a controlled A + "
                 f"{other} without.")
        out.append(line)
    return out


def _collision_counts_block(aggs: dict[str, AggregateMetrics]) -> list[str]:
    """report.md's lines of :func:`collision_count_lines` under their heading (none without collisions)."""
    lines = collision_count_lines(aggs)
    return ["Collision counts, reconciled:", "", *lines, ""] if lines else []


def _kind_order(item: tuple[str, int]) -> int:
    return COLLISION_KINDS.index(item[0]) if item[0] in COLLISION_KINDS else len(COLLISION_KINDS)


def flag_lines(aggs: dict[str, AggregateMetrics]) -> list[str]:
    """One warning line per flagged model (empty: none)."""
    def why(flags) -> str:
        said = []
        if any(f != "heldout_worse_than_uniform" for f in flags):
            said.append("its fit did not reach a usable maximum")
        if "heldout_worse_than_uniform" in flags:
            said.append("its held-out log-likelihood per step is below uniform actions' (log 1/5 = -1.609): it "
                        "predicts the held-out demonstrations worse than chance")
        return " and ".join(said)
    return [f"WARNING: model {name} is flagged ({', '.join(a.flags)}): {why(a.flags)}; do not rank or deploy it "
            "without checking" for name, a in aggs.items() if a.flags]


def _actions_line(controller) -> str:
    """How the drivers decided (report.md): by a fitted decision rule where a driver has one."""
    how = "at the mode of" if controller.mode else "drawn from"
    if getattr(controller, "rule", "fitted") == "fitted":
        return ("actions by a driver's fitted decision rule where it has one (the planning driver's most likely "
                f"acceleration), else {how} the driver's likelihood model")
    return f"actions {how} every driver's likelihood model (rule `likelihood-draw`)"


def _recorded_keys(recorded: RecordedComparison | None, name: str) -> dict:
    """A policy's keys beside the recorded drivers in metrics.json (``{}`` without them)."""
    d = recorded.drivers.get(name) if recorded is not None else None
    return d.to_dict() if d is not None else {}


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
                  left_out: list[str] | tuple[str, ...] = (), demo_closeness: DemoCloseness | None = None,
                  recorded: RecordedComparison | None = None):
    """Write report.md, metrics.json and the plots (:mod:`analysis.evaluation.plots`); return their
    paths. ``provenance`` (:func:`merge_irl.provenance.provenance`) goes into both; ``left_out``
    names the baselines that could not be fitted (no training demonstrations); ``demo_closeness``:
    the held-out encounters' share within ``metrics.close_gap_m`` of C (metrics.json's
    ``demos.close_to_c`` and the first row of the human-likeness table); ``recorded``: the drivers
    beside the recorded drivers (metrics.json's ``recorded_drivers`` and each policy's aggregate
    keys of :meth:`~analysis.evaluation.recorded.DriverVsRecorded.to_dict`, and the
    ``recorded drivers`` row and two columns of the human-likeness table)."""
    plots = write_plots(out, aggs, by_policy, held, speed_limit_ft_s=speed_limit_ft_s)
    payload = {
        "format": "merge-irl-evaluation/1",
        "scenario": scenario, "seed": seed, "episodes": episodes, "duration_s": duration_s,
        "controller": asdict(controller), "metrics_config": asdict(metrics),
        "demos": {"source": held.source, "action_counts": held.action_counts.tolist(),
                  "n_steps": int(len(held.encounters)),
                  **({"close_to_c": demo_closeness.to_dict()} if demo_closeness is not None else {})}
        if held is not None else None,
        "policies": {
            name: {"aggregate": {**a.to_dict(), **_recorded_keys(recorded, name)},
                   "episodes": [r.metrics.to_dict() for r in by_policy[name]]}
            for name, a in aggs.items()
        },
    }
    if recorded is not None:
        payload["recorded_drivers"] = recorded.recorded.to_dict()
    if provenance is not None:
        payload["provenance"] = provenance
    mj = write_text_atomic(out / "metrics.json", metrics_to_json(payload))
    lines = [
        f"# Closed-loop evaluation: {scenario}",
        "",
        f"{episodes} episode(s) per policy, seeds {seed}..{seed + episodes - 1} (the same traffic for every "
        f"policy); decision step {controller.decision_step_s} s, {_actions_line(controller)}, "
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
        collision_bound_line(aggs),
        "",
        *_collision_counts_block(aggs),
        emergency_line(metrics),
        "",
        column_legend(emergency_decel_m_s2=metrics.emergency_decel_m_s2,
                      emergency_tolerance_m_s2=metrics.emergency_tolerance_m_s2),
        "Baselines `marginal`, `markov`, `bc` (when run) are fitted on the training demonstrations (add-one "
        "smoothed). The JS divergence of A's action distribution to the demonstrations' is in metrics.json "
        "(`js_divergence`); the distributions themselves are below.",
        "",
        "Human likeness beside the held-out demonstrations"
        + (f" and the recorded drivers ({recorded.recorded.n_pairs} pairs of {recorded.recorded.source}):"
           if recorded is not None else ":"),
        "",
        human_table(aggs, demo_closeness, close_gap_m=metrics.close_gap_m, recorded=recorded),
        "",
        column_legend(human_columns(recorded), emergency_decel_m_s2=metrics.emergency_decel_m_s2,
                      close_gap_m=metrics.close_gap_m, emergency_tolerance_m_s2=metrics.emergency_tolerance_m_s2),
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
