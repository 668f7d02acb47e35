"""argparse types shared by the commands (argparse names the option and exits 2 on a bad value)."""

from __future__ import annotations

import argparse


def positive_int(text: str) -> int:
    """A whole number >= 1, e.g. ``--workers``.

    Raises:
        argparse.ArgumentTypeError: not a whole number, or below 1.
    """
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive whole number, got {text!r}") from None
    if n < 1:
        raise argparse.ArgumentTypeError(f"expected a positive whole number, got {n}")
    return n


def non_negative_int(text: str) -> int:
    """A whole number >= 0, e.g. a number of rounds where 0 means none.

    Raises:
        argparse.ArgumentTypeError: not a whole number, or below 0.
    """
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 0, got {text!r}") from None
    if n < 0:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 0, got {text!r}")
    return n
