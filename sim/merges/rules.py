"""The names of the ways a simulated run becomes demonstrations (:mod:`sim.merges.demonstrators`
describes them), in a module light enough for the command line's ``--help``."""

from __future__ import annotations

#: ``in-lane`` (default), ``take-over``, ``merge-frame``: see :mod:`sim.merges.demonstrators`.
ENCOUNTER_RULES = ("in-lane", "take-over", "merge-frame")


def check_rule(encounter_rule: str, *, custom_window: bool = False) -> None:
    """Raises ValueError for an unknown ``encounter_rule``, or for ``custom_window`` (an
    encounter window other than the default) with a rule that sets its own window (every rule
    but ``merge-frame``)."""
    if encounter_rule not in ENCOUNTER_RULES:
        raise ValueError(f"encounter rule must be one of {', '.join(ENCOUNTER_RULES)}; got {encounter_rule!r}")
    if custom_window and encounter_rule != "merge-frame":
        raise ValueError(f"an encounter window is for the merge-frame rule; {encounter_rule!r} sets its own")
