"""One fixed colour per policy, the same in every plot of the project (matplotlib colours)."""

from __future__ import annotations

import zlib

#: The held-out demonstrations, drawn as the reference in every plot.
DEMO_COLOR = "#111111"
#: Policy name -> colour: the IRL methods and the baselines.
POLICY_COLORS: dict[str, str] = {
    "demonstrations": DEMO_COLOR,
    "qavg": "#1f77b4",
    "qsm": "#ff7f0e",
    "mlirl": "#2ca02c",
    "reirl": "#d62728",
    "uniform": "#9a9a9a",
    "marginal": "#8c564b",
    "markov": "#e377c2",
    "bc": "#bcbd22",
    "sumo": "#9467bd",
}
#: Colours for other names, picked by a stable hash of the name (so a name keeps its colour).
_EXTRA = ("#17becf", "#aec7e8", "#ffbb78", "#98df8a", "#ff9896", "#c5b0d5", "#c49c94", "#f7b6d2", "#dbdb8d",
          "#9edae5", "#393b79", "#637939")


def policy_color(name: str) -> str:
    """The colour of policy ``name``: from :data:`POLICY_COLORS`, else (e.g. ``qavg-2`` or a
    custom policy) from the extra colours by a CRC-32 of the name, the same in every run."""
    if name in POLICY_COLORS:
        return POLICY_COLORS[name]
    return _EXTRA[zlib.crc32(name.encode()) % len(_EXTRA)]
