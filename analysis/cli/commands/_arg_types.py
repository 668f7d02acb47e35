"""argparse types shared by the commands (argparse names the option and exits 2 on a bad value)."""

from __future__ import annotations

import argparse
import sys


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


class DeprecatedFlag(argparse.Action):
    """A flag kept for one release under an old spelling: it sets ``dest`` to True, as the
    option that replaces it does, and writes one line on stderr naming that option
    (``merge-irl learn-driver: warning: --quiet is deprecated ...: use --no-progress``). Hidden
    from ``--help``; it sets nothing when not given (the new option holds the default).

    ``use``: the spelling to use instead, e.g. ``"--no-progress"``.
    """
    def __init__(self, option_strings, dest, *, use: str, **kw):
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, help=argparse.SUPPRESS, **kw)
        self.use = use

    def __call__(self, parser, namespace, values, option_string=None):
        print(f"{parser.prog}: warning: {option_string} is deprecated and goes in the next release: use {self.use}",
              file=sys.stderr, flush=True)
        setattr(namespace, self.dest, True)


class DeprecatedAlias(argparse.Action):
    """An option kept for one release under an old spelling that takes a value: it stores the value
    in ``dest``, as the option that replaces it does, and writes one line on stderr naming that
    option (``merge-irl calibrate fit: warning: --model is deprecated ...: use --cf-model-name``).
    Hidden from ``--help``; it sets nothing when not given (the new option holds the default).

    ``use``: the spelling to use instead, e.g. ``"--cf-model-name"``.
    """
    def __init__(self, option_strings, dest, *, use: str, **kw):
        kw.pop("help", None)
        kw.pop("default", None)
        super().__init__(option_strings, dest, default=argparse.SUPPRESS, help=argparse.SUPPRESS, **kw)
        self.use = use

    def __call__(self, parser, namespace, values, option_string=None):
        print(f"{parser.prog}: warning: {option_string} is deprecated and goes in the next release: use {self.use}",
              file=sys.stderr, flush=True)
        setattr(namespace, self.dest, values)


class Once(argparse.Action):
    """An option that takes one value and refuses being given again (argparse would silently keep
    the last: ``--demos a --demos b`` reading b alone). ``what``: what the one value is, for the
    message (e.g. ``"one encounter table"``); ``instead``: where several go, if anywhere."""
    def __init__(self, option_strings, dest, *, what: str = "one value", instead: str = "", **kw):
        super().__init__(option_strings, dest, **kw)
        self.what, self.instead = what, instead

    def __call__(self, parser, namespace, values, option_string=None):
        if getattr(namespace, self.dest, None) is not None and getattr(namespace, self.dest) != self.default:
            parser.error(f"{option_string} given twice ({getattr(namespace, self.dest)}, then {values}): this command "
                         f"reads {self.what}, and would keep only the last{'; ' + self.instead if self.instead else ''}")
        setattr(namespace, self.dest, values)
