"""The options of ``--executor dask://HOST:PORT`` / ``tls://HOST:PORT`` shared by the commands that
run sweeps (generate, evaluate, reproduce, demo).

They set Dask's configuration for this process (the home of Dask's settings: its files and
``DASK_*`` environment variables set the same keys), which
:mod:`analysis.sweep.dask_executor` reads.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

#: option destination -> Dask configuration key.
_KEYS = {
    "dask_connect_timeout": "distributed.comm.timeouts.connect",
    "dask_stall_timeout": "merge-irl.stall-timeout",
    "dask_tls_ca_file": "distributed.comm.tls.ca-file",
    "dask_tls_cert": "distributed.comm.tls.client.cert",
    "dask_tls_key": "distributed.comm.tls.client.key",
}


def _seconds(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of seconds, got {text!r}") from None
    if not (v > 0 and math.isfinite(v)):
        raise argparse.ArgumentTypeError(f"expected a positive number of seconds, got {text!r}")
    return v


def add_dask_options(p: argparse.ArgumentParser) -> None:
    """Add ``--dask-connect-timeout``, ``--dask-stall-timeout`` and the ``--dask-tls-*`` files."""
    from analysis.sweep.executors import DEFAULT_CONNECT_TIMEOUT_S, DEFAULT_STALL_TIMEOUT_S

    g = p.add_argument_group(
        "Dask scheduler (--executor dask://HOST:PORT or tls://HOST:PORT)",
        "The scheduler is sent pickled tasks and its results are unpickled here: use one you run, on a "
        "network you trust, or tls:// (docs/sweeps.md, Security). Unset options come from Dask's "
        "configuration (DASK_* environment variables, ~/.config/dask/*.yaml).")
    g.add_argument("--dask-connect-timeout", type=_seconds, default=None, metavar="S",
                   help=f"give up when the scheduler has not answered within S seconds "
                        f"(default: Dask's distributed.comm.timeouts.connect, {DEFAULT_CONNECT_TIMEOUT_S:g} s)")
    g.add_argument("--dask-stall-timeout", type=_seconds, default=None, metavar="S",
                   help=f"stop when none of the sweep's tasks has run on a worker for S seconds, e.g. every worker "
                        f"died (default {DEFAULT_STALL_TIMEOUT_S:g}; raise it for clusters whose workers start late)")
    g.add_argument("--dask-tls-ca-file", default=None, metavar="PEM",
                   help="tls://: CA certificate(s) the scheduler's certificate is checked against "
                        "(default: distributed.comm.tls.ca-file)")
    g.add_argument("--dask-tls-cert", default=None, metavar="PEM",
                   help="tls://: this client's certificate (default: distributed.comm.tls.client.cert)")
    g.add_argument("--dask-tls-key", default=None, metavar="PEM",
                   help="tls://: this client's private key (default: distributed.comm.tls.client.key, or appended "
                        "to the certificate)")


def apply_dask_options(args: argparse.Namespace) -> None:
    """Set the given options in Dask's configuration for the rest of this process.

    Raises:
        AnalysisError: a ``--dask-tls-*`` option given with an executor that is not ``tls://``
            (a ``dask://`` address would wait for a scheduler that answers TLS).
        FileNotFoundError: a ``--dask-tls-*`` file does not exist.
        AnalysisError: an option was given and Dask is not installed (one line, exit 2).
    """
    given = {key: getattr(args, dest) for dest, key in _KEYS.items() if getattr(args, dest, None) is not None}
    if not given:
        return
    tls_given = [f"--{d.replace('_', '-')}" for d in ("dask_tls_ca_file", "dask_tls_cert", "dask_tls_key")
                 if getattr(args, d, None) is not None]
    executor = (getattr(args, "executor", None) or "").strip()
    if tls_given and not executor.startswith("tls://"):
        from analysis.errors import AnalysisError

        where = f"--executor {executor}" if executor else "without --executor tls://HOST:PORT"
        fix = (f"use --executor tls://{executor[len('dask://'):]}" if executor.startswith("dask://")
               else "give --executor tls://HOST:PORT")
        raise AnalysisError(f"{', '.join(tls_given)} given {where}: the certificates are used only over TLS "
                            f"(dask:// is plain TCP); {fix}, or leave out {', '.join(tls_given)}")
    for dest in ("dask_tls_ca_file", "dask_tls_cert", "dask_tls_key"):
        path = getattr(args, dest, None)
        if path is not None and not Path(path).is_file():
            raise FileNotFoundError(f"--{dest.replace('_', '-')} {path}: no such file")
    try:
        import dask.config
    except ImportError:  # pragma: no cover - depends on the install
        from analysis.errors import AnalysisError

        raise AnalysisError("the --dask-* options need Dask distributed: pip install 'merge-irl[dask]'") from None
    dask.config.set({k: (f"{v}s" if isinstance(v, float) else str(Path(v).resolve())) for k, v in given.items()})
