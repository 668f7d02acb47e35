"""Metric thresholds for CI: ``--fail-if 'collisions>0'``.

Syntax of one threshold: ``[POLICY.]METRIC OP NUMBER`` with ``OP`` one of ``> >= < <= == !=``
(spaces allowed), e.g. ``collisions>0``, ``min_ttc_s < 1.5``, ``qavg.b_ahead_rate<=0.5``.
Several thresholds may be given (repeat the flag, or separate them with commas or ``;``); the
check fails if any of them holds. Without ``POLICY.`` a threshold applies to every policy of the
evaluation. A metric that is ``(mean, std)`` is compared by its mean. A metric whose value is
NaN (not measurable in that run) counts as a breach, so a CI gate never passes by accident.

Metric names are those of :class:`analysis.evaluation.aggregate.AggregateMetrics` (the ``aggregate`` object
of each policy in ``metrics.json``), plus :data:`EPISODE_TOTALS` (``teleports``: SUMO's teleports
summed over the policy's episodes).
"""

from __future__ import annotations

import json
import math
import operator
import re
import sys
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from analysis.errors import AnalysisError

OPERATORS = {">=": operator.ge, "<=": operator.le, "==": operator.eq, "!=": operator.ne,
             ">": operator.gt, "<": operator.lt}
_PATTERN = re.compile(
    r"^\s*(?:(?P<policy>[A-Za-z0-9_][A-Za-z0-9_.\-]*)\.)?(?P<metric>[A-Za-z_][A-Za-z0-9_]*)\s*"
    r"(?P<op>>=|<=|==|!=|>|<)\s*(?P<number>[^\s]+)\s*$"
)


class ThresholdError(AnalysisError, ValueError):
    """A threshold is malformed, names an unknown metric/policy, or a metrics file is unreadable."""


@dataclass(frozen=True)
class Threshold:
    """``metric op value``, optionally for one ``policy`` only ("" = every policy)."""

    metric: str
    op: str
    value: float
    policy: str = ""

    def holds(self, x: float) -> bool:
        """True when the failure condition holds for ``x`` (NaN always counts as holding)."""
        return math.isnan(x) or bool(OPERATORS[self.op](x, self.value))

    def __str__(self) -> str:
        who = f"{self.policy}." if self.policy else ""
        return f"{who}{self.metric}{self.op}{self.value:g}"


@dataclass(frozen=True)
class Breach:
    """A threshold that holds for one policy, with the value found."""

    threshold: Threshold
    policy: str
    value: float

    def __str__(self) -> str:
        shown = "NaN (not measured)" if math.isnan(self.value) else f"{self.value:g}"
        return f"{self.policy}: {self.threshold.metric} = {shown} (fail if {self.threshold})"


def parse_threshold(text: str) -> Threshold:
    """One ``[POLICY.]METRIC OP NUMBER``; ``ThresholdError`` explaining the syntax otherwise.

    Raises:
        ThresholdError: ``text`` is not ``[POLICY.]METRIC OP NUMBER`` with a known metric and a number (not
            NaN).
    """
    m = _PATTERN.match(text)
    if not m:
        raise ThresholdError(
            f"threshold {text!r}: expected METRIC OP NUMBER, e.g. 'collisions>0' "
            f"(OP one of {' '.join(sorted(OPERATORS, key=len))}; optional POLICY. prefix)")
    try:
        value = float(m["number"])
    except ValueError:
        raise ThresholdError(f"threshold {text!r}: {m['number']!r} is not a number") from None
    if math.isnan(value):
        raise ThresholdError(f"threshold {text!r}: the number must not be NaN")
    return Threshold(metric=m["metric"], op=m["op"], value=value, policy=m["policy"] or "")


def parse_thresholds(texts: Iterable[str] | str) -> tuple[Threshold, ...]:
    """Several thresholds: an iterable of strings, each possibly ``,``/``;``-separated.

    Raises:
        ThresholdError: a part that is not ``[POLICY.]METRIC OP NUMBER``.
    """
    if isinstance(texts, str):
        texts = [texts]
    out = []
    for text in texts:
        for part in re.split(r"[;,]", text):
            if part.strip():
                out.append(parse_threshold(part))
    return tuple(out)


def _scalar(value: Any) -> float | None:
    if isinstance(value, bool):
        return float(value)
    if isinstance(value, (int, float)):
        return float(value)
    if isinstance(value, (list, tuple)) and value and isinstance(value[0], (int, float)) \
            and not isinstance(value[0], bool):
        return float(value[0])  # (mean, std): the mean
    if value is None:
        return float("nan")
    return None


def check_thresholds(thresholds: Iterable[Threshold],
                     metrics: Mapping[str, Mapping[str, Any]]) -> list[Breach]:
    """Breaches of ``thresholds`` in ``metrics`` (``policy -> metric name -> value``).

    Raises:
        ThresholdError: a threshold names a metric that no policy has (listing the known,
            numeric ones) or a policy that is not in ``metrics``.
    """
    thresholds = tuple(thresholds)
    if not metrics:
        raise ThresholdError("no policies in the metrics to check thresholds against")
    numeric = sorted({k for m in metrics.values() for k, v in m.items() if _scalar(v) is not None})
    breaches = []
    for t in thresholds:
        if t.policy and t.policy not in metrics:
            raise ThresholdError(f"threshold '{t}': unknown policy {t.policy!r}; policies: {', '.join(metrics)}")
        if t.metric not in numeric:
            raise ThresholdError(f"threshold '{t}': unknown metric {t.metric!r}; metrics: {', '.join(numeric)}")
        for policy, values in metrics.items():
            if t.policy and policy != t.policy:
                continue
            x = _scalar(values.get(t.metric))
            if x is None:
                continue
            if t.holds(x):
                breaches.append(Breach(t, policy, x))
    return breaches


def not_triggered(thresholds: Iterable[Threshold], metrics: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """One line per threshold that holds for no policy, with the values found, e.g.
    ``"ok: teleports = 0 (every policy); gate teleports>0 not triggered"`` (the values, then the gate,
    so that the line does not read as if the condition had occurred).

    Raises:
        ThresholdError: as :func:`check_thresholds`.
    """
    thresholds = tuple(thresholds)
    breached = {b.threshold for b in check_thresholds(thresholds, metrics)}
    lines = []
    for t in thresholds:
        if t in breached:
            continue
        found = [(p, x) for p, m in metrics.items() if (not t.policy or p == t.policy)
                 and (x := _scalar(m.get(t.metric))) is not None]
        values = {f"{x:g}" for _, x in found}
        if not values:
            shown = "no numeric value"
        elif len(values) == 1:
            shown = values.pop() + ("" if t.policy else f" ({'every policy' if len(found) > 1 else found[0][0]})")
        else:
            shown = ", ".join(f"{x:g} ({p})" for p, x in found)
        who = f"{t.policy}." if t.policy else ""
        lines.append(f"ok: {who}{t.metric} = {shown}; gate {t} not triggered")
    return lines


def metrics_from_file(path: str | Path) -> dict[str, dict[str, Any]]:
    """``policy -> aggregate metrics`` of an evaluation's ``metrics.json``.

    Raises:
        ThresholdError: the file is missing, not readable JSON, or has no ``policies`` object of ``{name:
            {"aggregate": {...}}}``.
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ThresholdError(f"{path}: no such metrics file") from None
    except (OSError, ValueError) as e:
        raise ThresholdError(f"{path}: not a readable metrics.json ({e})") from None
    policies = data.get("policies") if isinstance(data, dict) else None
    if not isinstance(policies, dict) or not all(
            isinstance(p, dict) and isinstance(p.get("aggregate"), dict) for p in policies.values()):
        raise ThresholdError(f"{path}: expected an object 'policies' of {{name: {{'aggregate': {{...}}}}}}")
    return {name: {**_episode_totals(p.get("episodes")), **p["aggregate"]} for name, p in policies.items()}


#: Whole-run counts of the episodes that a ``metrics.json`` aggregate may lack; thresholds see
#: their total over the policy's episodes (``--fail-if 'teleports>0'``).
EPISODE_TOTALS = ("teleports",)


def _episode_totals(episodes: Any) -> dict[str, int]:
    if not isinstance(episodes, list) or not all(isinstance(e, dict) for e in episodes):
        return {}
    return {k: sum(int(e[k]) for e in episodes) for k in EPISODE_TOTALS
            if episodes and all(isinstance(e.get(k), int) and not isinstance(e.get(k), bool) for e in episodes)}


def check_file(path: str | Path, thresholds: Iterable[str] | str) -> list[Breach]:
    """Parse ``thresholds`` and check them against ``metrics.json`` at ``path``.

    Raises:
        ThresholdError: a malformed threshold, a missing or malformed metrics file, or an
            unknown policy or metric name.
    """
    return check_thresholds(parse_thresholds(thresholds), metrics_from_file(path))


def gate(thresholds: tuple[Threshold, ...], path: str | Path, *, err: Any = None) -> int:
    """The command-line gate of ``merge-irl check-metrics`` and ``evaluate --fail-if``: each
    breach of ``thresholds`` in the metrics file ``path`` as a ``FAIL ...`` line and each
    threshold that held as its own line, on ``err`` (default stderr); 1 if any breach, else 0.

    Raises:
        ThresholdError: a missing or malformed metrics file, or an unknown policy or metric name.
    """
    out = sys.stderr if err is None else err
    metrics = metrics_from_file(path)
    breaches = check_thresholds(thresholds, metrics)
    for b in breaches:
        print(f"FAIL {b}", file=out)
    for line in not_triggered(thresholds, metrics):
        print(line, file=out)
    return 1 if breaches else 0
