"""The evaluation's PNG plots (matplotlib Agg), each against the held-out demonstrations.

Every plot draws the demonstrations (when given) as the black reference, spreads as bands or
quantiles, the sample count of each series in the legend, one colour per policy
(:func:`analysis.evaluation.palette.policy_color`), and marks implausible values: a speed of A above
:data:`IMPLAUSIBLE_SPEED_FACTOR` times the speed limit, a braking beyond
:data:`PHYSICAL_BRAKING_FT_S2` (1 g). The plots with bands (gap acceptance, speed profiles) are
small multiples, one panel per policy against the demonstrations, so that no band hides another.

Inputs: ``by_policy`` maps a policy name to its :class:`analysis.evaluation.episode.EpisodeResult` list;
``held`` is an :class:`analysis.evaluation.heldout_scoring.HeldOut` or None. Units ft, ft/s, ft/s^2, s.
"""

from __future__ import annotations

from itertools import pairwise
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.stats import binomtest

from analysis.evaluation.palette import policy_color
from irl.domains.merge.actions import ACTION_NAMES, N_ACTIONS
from merge_irl.atomic import write_atomic
from merge_irl.units import FRAME_S, FT_PER_M

#: Braking beyond 1 g (ft/s^2, negative) is beyond what tyres can do: marked implausible.
PHYSICAL_BRAKING_FT_S2 = -9.81 * FT_PER_M
#: A speed above this multiple of the speed limit is marked implausible.
IMPLAUSIBLE_SPEED_FACTOR = 1.3
#: Speed limit (ft/s) when none is given: the scenarios' default, 29 m/s.
DEFAULT_SPEED_LIMIT_FT_S = 29.0 * FT_PER_M
#: Gap bins (ft) of the gap acceptance plot.
GAP_BINS_FT = (0.0, 50.0, 100.0, 150.0, 200.0)


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


def _concat(rs, attr: str) -> pd.DataFrame:
    parts = [getattr(r, attr) for r in rs if len(getattr(r, attr))]
    return pd.concat(parts, ignore_index=True) if parts else pd.DataFrame()


def _legend(ax, size: int) -> None:
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=size)


def _panels(plt, n: int, *, width: float = 3.6, height: float = 2.9):
    """A figure of ``n`` panels (at most 4 a row, shared axes; spare cells hidden) and its axes
    in reading order."""
    cols = min(4, max(1, n))
    rows = -(-max(1, n) // cols)
    fig, grid = plt.subplots(rows, cols, figsize=(width * cols, height * rows + 0.6), sharex=True, sharey=True,
                             squeeze=False)
    axes = list(grid.ravel())
    for ax in axes[n:]:
        ax.set_visible(False)
    for i, ax in enumerate(axes[:max(1, n)]):
        # the x tick labels on every panel with no panel below it (shared axes hide the others)
        ax.xaxis.set_tick_params(labelbottom=i + cols >= max(1, n))
    return fig, axes[:max(1, n)]


def _no_data(ax, what: str) -> None:
    ax.text(0.5, 0.5, f"no {what}", transform=ax.transAxes, ha="center", va="center", color="0.4")


# -- samples of each quantity ------------------------------------------------------------

def policy_accelerations(rs) -> np.ndarray:
    """``[n]`` accelerations of A (ft/s^2) while controlled: forward differences of the speed
    profiles over one frame (as the demonstrations' ``acc_A``)."""
    sp = _concat(rs, "speed_profiles")
    if sp.empty:
        return np.zeros(0)
    out = []
    for _, g in sp.groupby("a_id", sort=False):
        # one control episode of an A is one run of consecutive frames; a new episode restarts t_s at 0
        t, v = g["t_s"].to_numpy(float), g["v_ft_s"].to_numpy(float)
        ok = np.isclose(np.diff(t), FRAME_S)
        out.append((np.diff(v) / FRAME_S)[ok])
    return np.concatenate(out) if out else np.zeros(0)


def demo_merges(held) -> pd.DataFrame:
    """One row per demonstrated encounter: ``gap_AB_start_ft`` (d_AB at its first frame) and
    ``b_ahead`` (B ahead of A at B's merge frame, or at the last frame before it; the last
    frame when the table has no ``merge_frame``). Empty without ``encounter_id``/``Frame_ID``."""
    need = {"encounter_id", "Frame_ID", "d_AB"}
    if held is None or held.encounters.empty or not need <= set(held.encounters.columns):
        return pd.DataFrame({"gap_AB_start_ft": pd.Series(dtype=float), "b_ahead": pd.Series(dtype=bool)})
    df = held.encounters.sort_values(["encounter_id", "Frame_ID"])
    rows = []
    for _, g in df.groupby("encounter_id", sort=False):
        at = g[g["Frame_ID"] <= g["merge_frame"].iloc[0]] if "merge_frame" in g else g
        last = at.iloc[-1] if len(at) else g.iloc[-1]
        rows.append((float(g["d_AB"].iloc[0]), bool(last["d_AB"] > 0)))
    return pd.DataFrame(rows, columns=["gap_AB_start_ft", "b_ahead"])


# -- plots ---------------------------------------------------------------------------------

def plot_action_histograms(path: Path, aggs, held) -> Path:
    """Share of A's decisions per action, demonstrations first; counts in the legend."""
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
        n = c.sum()
        ax.bar(x + i * w - 0.4 + w / 2, c / n if n else c, width=w, color=policy_color(name),
               label=f"{name} (n={int(n)} decisions)", hatch="//" if name == "demonstrations" else None,
               edgecolor="white" if name == "demonstrations" else None)
    ax.set_xticks(x, ACTION_NAMES)
    ax.set_ylabel("share of decisions")
    ax.set_title("Action of car A")
    _legend(ax, 8)
    return _save(fig, path)


def _rate_band(k: np.ndarray, y: np.ndarray, n_bins: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per bin: share of True in ``y`` and its 95 % Clopper-Pearson interval (NaN when empty)."""
    rate, lo, hi = (np.full(n_bins, np.nan) for _ in range(3))
    for j in range(n_bins):
        m = k == j
        if m.any():
            s = int(y[m].sum())
            ci = binomtest(s, int(m.sum())).proportion_ci(0.95, method="exact")
            rate[j], lo[j], hi[j] = s / m.sum(), ci.low, ci.high
    return rate, lo, hi


def plot_gap_acceptance(path: Path, by_policy, held=None) -> Path:
    """Share of merges with B ahead of A by the gap d_AB at take-over (ft), with 95 % bands: one
    panel per policy, each with the demonstrations (dashed, black) as the reference."""
    plt = _plt()
    edges = np.asarray(GAP_BINS_FT)
    labels = ["<0"] + [f"{int(a)}-{int(b)}" for a, b in pairwise(edges)] + [f">{int(edges[-1])}"]
    x = np.arange(len(labels))
    dm = demo_merges(held)
    series = {}
    for name, rs in by_policy.items():
        ct = _concat(rs, "controls")
        if not ct.empty:
            ct = ct[ct["merge_frame"] >= 0]
        if not ct.empty:
            series[name] = ct
    names = list(series) or [None]
    fig, axes = _panels(plt, len(names))

    def draw(ax, name: str, ct: pd.DataFrame) -> None:
        k = np.digitize(ct["gap_AB_start_ft"].to_numpy(float), edges)
        rate, lo, hi = _rate_band(k, ct["b_ahead"].to_numpy(bool), len(labels))
        demo = name == "demonstrations"
        c = policy_color(name)
        ax.plot(x, rate, marker="o", color=c, lw=2.0 if demo else 1.8, ls="--" if demo else "-",
                label=f"{name} (n={len(ct)} merges)", zorder=3 if demo else 2)
        ax.fill_between(x, lo, hi, color=c, alpha=0.12 if demo else 0.22, lw=0)

    for ax, name in zip(axes, names):
        if len(dm):
            draw(ax, "demonstrations", dm)
        if name is not None:
            draw(ax, name, series[name])
            ax.set_title(name, fontsize=10, color=policy_color(name))
        elif not len(dm):
            _no_data(ax, "merges")
        ax.set_xticks(x, labels, fontsize=7)
        ax.set_ylim(-0.05, 1.05)
        _legend(ax, 7)
    _label_outer(axes, "gap d_AB at take-over (ft)", "share with B ahead of A")
    fig.suptitle("Gap acceptance, one panel per policy against the demonstrations (bands: 95 % interval)",
                 fontsize=10)
    return _save(fig, path)


def plot_speed_profiles(path: Path, by_policy, held=None, *, speed_limit_ft_s: float | None = None) -> Path:
    """Median speed of A against time since take-over, 10-90 % band, one panel per policy (with
    the demonstrations where they have speeds); implausible speeds marked and counted.

    The encounter table holds no absolute speed, so the demonstrations appear here only when
    their table has a ``v_A`` column (ft/s) and a ``Frame_ID`` from which the time since the
    encounter's first frame is taken.
    """
    plt = _plt()
    limit = DEFAULT_SPEED_LIMIT_FT_S if speed_limit_ft_s is None else float(speed_limit_ft_s)
    too_fast = IMPLAUSIBLE_SPEED_FACTOR * limit
    demo = None
    if held is not None and {"v_A", "Frame_ID", "encounter_id"} <= set(held.encounters.columns):
        e = held.encounters
        t = (e["Frame_ID"] - e.groupby("encounter_id")["Frame_ID"].transform("min")) * FRAME_S
        demo = (pd.DataFrame({"t_s": t, "v_ft_s": e["v_A"]}), e["encounter_id"].nunique())
    series = {}
    for name, rs in by_policy.items():
        sp = _concat(rs, "speed_profiles")
        if not sp.empty:
            series[name] = (sp, int(sum(len(r.controls) for r in rs)))
    names = list(series) or [None]
    fig, axes = _panels(plt, len(names))

    def draw(ax, name: str, sp: pd.DataFrame, n: int) -> None:
        g = sp.assign(t=np.round(sp["t_s"].to_numpy(float), 1)).groupby("t")["v_ft_s"]
        q = g.quantile([0.1, 0.5, 0.9]).unstack()
        size = g.size()
        q = q[size >= 2] if (size >= 2).any() else q
        c = policy_color(name)
        bad = sp["v_ft_s"].to_numpy(float) > too_fast
        tag = f", {int(bad.sum())} samples implausible" if bad.any() else ""
        is_demo = name == "demonstrations"
        ax.plot(q.index, q[0.5], color=c, lw=2.0 if is_demo else 1.8, ls="--" if is_demo else "-",
                label=f"{name} (n={n} {'encounters' if is_demo else 'take-overs'}{tag})")
        ax.fill_between(q.index, q[0.1], q[0.9], color=c, alpha=0.12 if is_demo else 0.2, lw=0)
        if bad.any():
            ax.scatter(sp["t_s"].to_numpy(float)[bad], sp["v_ft_s"].to_numpy(float)[bad], marker="x", s=14, color=c)

    for i, (ax, name) in enumerate(zip(axes, names)):
        if demo is not None:
            draw(ax, "demonstrations", *demo)
        if name is not None:
            draw(ax, name, *series[name])
            ax.set_title(name, fontsize=10, color=policy_color(name))
        elif demo is None:
            _no_data(ax, "controlled car")
        # the two reference lines are named once, in the first panel's legend
        ax.axhline(limit, color="0.5", lw=0.8, ls=":", label=f"speed limit {limit:.0f} ft/s" if i == 0 else None)
        ax.axhline(too_fast, color="#b00000", lw=1.0, ls="--",
                   label=(f"implausible above {too_fast:.0f} ft/s ({IMPLAUSIBLE_SPEED_FACTOR:g} x limit; x = sample)"
                          if i == 0 else None))
        _legend(ax, 6)
    _label_outer(axes, "time since take-over (s)", "speed of A (ft/s)")
    title = "Speed of A: median, 10-90 % band, one panel per policy"
    if held is not None and demo is None:
        title += "\n(demonstrations: the encounter table has no absolute speed)"
    fig.suptitle(title, fontsize=10)
    return _save(fig, path)


def _distribution(ax, series: dict[str, np.ndarray], bins: np.ndarray, unit: str) -> None:
    """Step histograms (density), a band between the 25 and 75 % quantiles under each curve's
    colour on the x axis, median and n in the legend."""
    quart = []
    for name, v in series.items():
        v = v[np.isfinite(v)]
        if v.size == 0:
            continue
        demo = name == "demonstrations"
        c = policy_color(name)
        q25, q50, q75 = np.quantile(v, [0.25, 0.5, 0.75])
        ax.hist(np.clip(v, bins[0], bins[-1]), bins=bins, density=True, histtype="step", color=c,
                lw=2.5 if demo else 1.4, ls="--" if demo else "-",
                label=f"{name} (n={v.size}, median {q50:.1f} {unit})")
        quart.append((q25, q75, c))
    top = ax.get_ylim()[1]
    for i, (q25, q75, c) in enumerate(quart):
        ax.plot([q25, q75], [-0.04 * top * (i + 1)] * 2, color=c, lw=4, solid_capstyle="butt")
    ax.set_ylabel("density (bars under the axis: 25-75 %)")


def plot_acceleration(path: Path, by_policy, held=None) -> Path:
    """Distribution of A's acceleration (ft/s^2) while controlled; braking beyond 1 g marked."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 4))
    series = {}
    if held is not None and "acc_A" in held.encounters:
        series["demonstrations"] = held.encounters["acc_A"].to_numpy(float)
    for name, rs in by_policy.items():
        a = policy_accelerations(rs)
        if a.size:
            series[name] = a
    lo = min([PHYSICAL_BRAKING_FT_S2 * 1.3] + [float(np.nanmin(v)) for v in series.values() if v.size])
    hi = max([15.0] + [float(np.nanmax(v)) for v in series.values() if v.size])
    _distribution(ax, series, np.linspace(max(lo, -80.0), min(hi, 40.0), 61), "ft/s^2")
    if not series:
        _no_data(ax, "acceleration")
    n_beyond = {k: int((v < PHYSICAL_BRAKING_FT_S2).sum()) for k, v in series.items()}
    beyond = ", ".join(f"{k} {n}" for k, n in n_beyond.items() if n) or "none"
    ax.axvline(PHYSICAL_BRAKING_FT_S2, color="#b00000", ls="--", lw=1.0,
               label=f"braking beyond 1 g ({PHYSICAL_BRAKING_FT_S2:.1f} ft/s^2): {beyond}")
    ax.axvspan(ax.get_xlim()[0], PHYSICAL_BRAKING_FT_S2, color="#b00000", alpha=0.06)
    ax.set_xlabel("acceleration of A (ft/s^2), forward difference over 0.1 s")
    ax.set_title("Acceleration of A while controlled")
    _legend(ax, 7)
    return _save(fig, path)


def plot_headway(path: Path, by_policy, held=None) -> Path:
    """Distribution of the headway d_AC (ft) from A to its lead car C, at A's decisions."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 4))
    series = {}
    if held is not None and "d_AC" in held.encounters:
        series["demonstrations"] = held.encounters["d_AC"].to_numpy(float)
    for name, rs in by_policy.items():
        d = _concat(rs, "decisions")
        if not d.empty:
            series[name] = d["d_AC"].to_numpy(float)
    fin = [v[np.isfinite(v)] for v in series.values()]
    top = max([200.0] + [float(np.quantile(v, 0.98)) for v in fin if v.size])
    _distribution(ax, series, np.linspace(0.0, top, 41), "ft")
    if not any(v.size for v in fin):
        _no_data(ax, "lead car C")
    ax.set_xlabel("headway d_AC from A to its lead car C (ft; larger values in the last bin)")
    ax.set_title("Headway of A (decisions with a lead car)")
    _legend(ax, 7)
    return _save(fig, path)


def write_plots(out: Path, aggs, by_policy, held, *, speed_limit_ft_s: float | None = None) -> tuple[Path, ...]:
    """All evaluation plots into ``out``; their paths."""
    out = Path(out)
    return (
        plot_action_histograms(out / "action_histograms.png", aggs, held),
        plot_gap_acceptance(out / "gap_acceptance.png", by_policy, held),
        plot_speed_profiles(out / "speed_profiles.png", by_policy, held, speed_limit_ft_s=speed_limit_ft_s),
        plot_acceleration(out / "acceleration.png", by_policy, held),
        plot_headway(out / "headway.png", by_policy, held),
    )


def _label_outer(axes, xlabel: str, ylabel: str) -> None:
    """Axis labels of small multiples: x on the panels with tick labels at the bottom, y on the first column."""
    for ax in axes:
        if ax.xaxis.get_tick_params()["labelbottom"]:
            ax.set_xlabel(xlabel, fontsize=8)
        if ax.get_subplotspec().is_first_col():
            ax.set_ylabel(ylabel, fontsize=8)
