"""One fixed colour per policy, the same in every plot of the project (matplotlib colours).

The learned drivers the demo evaluates (``planner``, ``cf-dagger``, ``cf-logit``) and the reference
drivers (``sumo-in-lane``, ``idm``) have fixed, saturated colours; the trivial baselines the
lighter ones. Only names outside :data:`POLICY_COLORS` take a colour by hash.
"""

from __future__ import annotations

import zlib

#: The held-out demonstrations, drawn as the reference in every plot.
DEMO_COLOR = "#111111"
#: Policy name -> colour: the IRL methods and the baselines.
POLICY_COLORS: dict[str, str] = {
    "demonstrations": DEMO_COLOR,
    "planner": "#d62728",
    "cf-dagger": "#17becf",
    "cf-logit": "#393b79",
    "qavg": "#1f77b4",
    "qsm": "#ff7f0e",
    "mlirl": "#2ca02c",
    "reirl": "#7b4173",
    "uniform": "#9a9a9a",
    "marginal": "#8c564b",
    "markov": "#e377c2",
    "bc": "#bcbd22",
    "sumo": "#6a3d9a",
    "sumo-in-lane": "#637939",
    "idm": "#843c39",
}
#: Colours for other names, picked by a stable hash of the name (so a name keeps its colour).
_EXTRA = ("#aec7e8", "#ffbb78", "#98df8a", "#ff9896", "#c5b0d5", "#c49c94", "#f7b6d2", "#dbdb8d",
          "#9edae5", "#e7ba52", "#6b6ecf", "#b5cf6b")


def policy_color(name: str) -> str:
    """The colour of policy ``name``: from :data:`POLICY_COLORS`, else (e.g. ``qavg-2`` or a
    custom policy) from the extra colours by a CRC-32 of the name, the same in every run."""
    if name in POLICY_COLORS:
        return POLICY_COLORS[name]
    return _EXTRA[zlib.crc32(name.encode()) % len(_EXTRA)]
