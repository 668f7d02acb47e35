"""argparse types shared by the commands (argparse names the option and exits 2 on a bad value)."""

from __future__ import annotations

import argparse


def _whole_number_at_least(text: str, lowest: int, wanted: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {wanted}, got {text!r}") from None
    if n < lowest:
        raise argparse.ArgumentTypeError(f"expected {wanted}, got {n}")
    return n


def positive_int(text: str) -> int:
    """A whole number >= 1, e.g. ``--workers``.

    Raises:
        argparse.ArgumentTypeError: not a whole number, or below 1.
    """
    return _whole_number_at_least(text, 1, "a positive whole number")


def non_negative_int(text: str) -> int:
    """A whole number >= 0, e.g. a number of rounds where 0 means none.

    Raises:
        argparse.ArgumentTypeError: not a whole number, or below 0.
    """
    return _whole_number_at_least(text, 0, "a whole number >= 0")


def add_allow_implausible(p: argparse.ArgumentParser) -> None:
    """``--allow-implausible``: run a scenario or ``--duration`` outside the plausibility bounds
    (``scenarios.spec.bounds``), as the scenario file's own ``allow_implausible = true`` does."""
    p.add_argument("--allow-implausible", action="store_true",
                   help="run values outside the plausibility bounds (e.g. --duration above 6 h, a demand above "
                        "10,000 veh/h per lane, a speed limit above 45 m/s) instead of refusing them "
                        "(docs: scenarios, 'Plausibility bounds')")
