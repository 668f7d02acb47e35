"""The options several ``merge-irl`` commands share, each defined once, with one default.

A command takes them as argparse parents (``subparsers.add_parser(name, parents=[WORKERS, ...])``):
the same option string then has the same destination, type, repetition rule and default in every
command, which ``tests/analysis/cli/test_option_meanings.py`` checks over the whole parser tree.

* :data:`WORKERS` ``--workers N``: processes (default None: every core, through
  :func:`analysis.sweep.resolve_executor`).
* :data:`EXECUTOR` ``--executor EXEC``: where the runs go (default None: ``process:<--workers>``,
  else every core); :func:`executor_from_args` resolves it.
* :data:`PROGRESS` ``--no-progress``.
* :data:`DASK` the ``--dask-*`` options of ``--executor dask://`` and ``tls://``;
  :func:`apply_dask_options` sets them in Dask's configuration.
* :func:`seed_option` ``--seed N`` (default 0), :data:`EPISODES` ``--episodes N`` (default 3),
  :func:`demos_option` ``--demos PATH...`` (every value read: repeated or listed).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from analysis.cli.commands._arg_types import positive_int
from analysis.errors import AnalysisError
from analysis.sweep.executors import DEFAULT_CONNECT_TIMEOUT_S, DEFAULT_STALL_TIMEOUT_S, resolve_executor


def _parent() -> argparse.ArgumentParser:
    return argparse.ArgumentParser(add_help=False)


WORKERS = _parent()
WORKERS.add_argument("--workers", type=positive_int, default=None, metavar="N",
                     help="processes running the tasks (SUMO runs, fits), one at a time each (default: every core); "
                          "in a command with --executor, short for --executor process:N")

EXECUTOR = _parent()
EXECUTOR.add_argument("--executor", default=None, metavar="EXEC",
                      help="where the runs go: serial, process[:N], dask-local[:N], dask://HOST:PORT, "
                           "tls://HOST:PORT (default: process:<--workers> if given, else every core); results do "
                           "not depend on it")

PROGRESS = _parent()
PROGRESS.add_argument("--no-progress", action="store_true", help="no progress bars or lines on stderr")

EPISODES = _parent()
EPISODES.add_argument("--episodes", type=positive_int, default=3, metavar="N",
                      help="evaluation episodes (seeds) per policy (default 3)")


def seed_option(what: str) -> argparse.ArgumentParser:
    """A parent holding ``--seed N`` (int, default 0); ``what``: what it seeds, for the help."""
    p = _parent()
    p.add_argument("--seed", type=int, default=0, metavar="N", help=f"{what} (default 0)")
    return p


def demos_option(help: str, *, required: bool = False) -> argparse.ArgumentParser:
    """A parent holding ``--demos PATH...``: every value is read, repeated (``--demos a --demos b``)
    or listed (``--demos a b``); the command keeps them apart as sources or merges them, as its
    help says. Never refused and never "last wins"."""
    p = _parent()
    p.add_argument("--demos", nargs="+", action="extend", default=None, required=required, metavar="PATH",
                   help=f"{help} (repeat or list several: --demos a b and --demos a --demos b read both)")
    return p


def executor_from_args(args: argparse.Namespace) -> str:
    """The executor spec of ``--executor`` / ``--workers`` (a command without ``--workers``: every
    core by default).

    Raises:
        AnalysisError: both given, or a spec that does not parse (one line, exit 2).
    """
    workers = getattr(args, "workers", None)
    if args.executor is not None and workers is not None:
        raise AnalysisError("give --executor or --workers, not both")
    return resolve_executor(args.executor, workers)


#: option destination -> Dask configuration key.
_KEYS = {
    "dask_connect_timeout": "distributed.comm.timeouts.connect",
    "dask_stall_timeout": "merge-irl.stall-timeout",
    "dask_tls_ca_file": "distributed.comm.tls.ca-file",
    "dask_tls_cert": "distributed.comm.tls.client.cert",
    "dask_tls_key": "distributed.comm.tls.client.key",
}
_TLS = ("dask_tls_ca_file", "dask_tls_cert", "dask_tls_key")


def _seconds(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of seconds, got {text!r}") from None
    if not (v > 0 and math.isfinite(v)):
        raise argparse.ArgumentTypeError(f"expected a positive number of seconds, got {text!r}")
    return v


DASK = _parent()
_g = DASK.add_argument_group(
    "Dask scheduler (--executor dask://HOST:PORT or tls://HOST:PORT)",
    "The scheduler is sent pickled tasks and its results are unpickled here: use one you run, on a "
    "network you trust, or tls:// (docs/sweeps.md, Security). Unset options come from Dask's "
    "configuration (DASK_* environment variables, ~/.config/dask/*.yaml).")
_g.add_argument("--dask-connect-timeout", type=_seconds, default=None, metavar="S",
                help=f"give up when the scheduler has not answered within S seconds "
                     f"(default: Dask's distributed.comm.timeouts.connect, {DEFAULT_CONNECT_TIMEOUT_S:g} s)")
_g.add_argument("--dask-stall-timeout", type=_seconds, default=None, metavar="S",
                help=f"stop when none of the sweep's tasks has run on a worker for S seconds, e.g. every worker "
                     f"died (default {DEFAULT_STALL_TIMEOUT_S:g}; raise it for clusters whose workers start late)")
_g.add_argument("--dask-tls-ca-file", default=None, metavar="PEM",
                help="tls://: CA certificate(s) the scheduler's certificate is checked against "
                     "(default: distributed.comm.tls.ca-file)")
_g.add_argument("--dask-tls-cert", default=None, metavar="PEM",
                help="tls://: this client's certificate (default: distributed.comm.tls.client.cert)")
_g.add_argument("--dask-tls-key", default=None, metavar="PEM",
                help="tls://: this client's private key (default: distributed.comm.tls.client.key, or appended "
                     "to the certificate)")


def _check_tls(args: argparse.Namespace) -> None:
    tls_given = [f"--{d.replace('_', '-')}" for d in _TLS if getattr(args, d, None) is not None]
    executor = (getattr(args, "executor", None) or "").strip()
    if tls_given and not executor.startswith("tls://"):
        where = f"--executor {executor}" if executor else "without --executor tls://HOST:PORT"
        fix = (f"use --executor tls://{executor[len('dask://'):]}" if executor.startswith("dask://")
               else "give --executor tls://HOST:PORT")
        raise AnalysisError(f"{', '.join(tls_given)} given {where}: the certificates are used only over TLS "
                            f"(dask:// is plain TCP); {fix}, or leave out {', '.join(tls_given)}")
    for dest in _TLS:
        path = getattr(args, dest, None)
        if path is not None and not Path(path).is_file():
            raise FileNotFoundError(f"--{dest.replace('_', '-')} {path}: no such file")


def apply_dask_options(args: argparse.Namespace) -> None:
    """Set the given ``--dask-*`` options in Dask's configuration for the rest of this process
    (the home of Dask's settings: its files and ``DASK_*`` environment variables set the same
    keys), which :mod:`analysis.sweep.dask_executor` reads.

    Raises:
        AnalysisError: a ``--dask-tls-*`` option given with an executor that is not ``tls://``
            (a ``dask://`` address would wait for a scheduler that answers TLS).
        FileNotFoundError: a ``--dask-tls-*`` file does not exist.
        AnalysisError: an option was given and Dask is not installed (one line, exit 2).
    """
    given = {key: getattr(args, dest) for dest, key in _KEYS.items() if getattr(args, dest, None) is not None}
    if not given:
        return
    _check_tls(args)
    try:
        import dask.config  # optional dependency (merge-irl[dask]): only when a --dask-* option is given
    except ImportError:  # pragma: no cover - depends on the install
        raise AnalysisError("the --dask-* options need Dask distributed: pip install 'merge-irl[dask]'") from None
    dask.config.set({k: (f"{v}s" if isinstance(v, float) else str(Path(v).resolve())) for k, v in given.items()})
