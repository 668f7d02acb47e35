"""Executors: where a sweep's tasks run.

- ``serial``: in this process, one after the other (debugging, tiny sweeps).
- ``process`` / ``process:N``: a local process pool with N workers (default: every core),
  fresh ``spawn`` processes, so each task can own a libsumo simulation.
- ``dask-local`` / ``dask-local:N``: a Dask ``LocalCluster`` on the loopback interface.
- ``dask://HOST:PORT``: an existing Dask distributed scheduler (more than one machine), plain TCP.
- ``tls://HOST:PORT``: the same over TLS, with Dask's security settings (certificates named by
  :class:`DaskSettings` or Dask's configuration ``distributed.comm.tls.*``).

A Dask scheduler is sent pickled tasks and its results are unpickled here: whoever answers on the
address can run code on this machine and on the workers (docs/sweeps.md, "Security").
"""

from __future__ import annotations

import os
from dataclasses import dataclass

from analysis.errors import AnalysisError

EXECUTORS = ("serial", "process", "dask-local", "dask://HOST:PORT", "tls://HOST:PORT")

#: Seconds to wait for a Dask scheduler to answer (TCP connect and Dask's handshake).
DEFAULT_CONNECT_TIMEOUT_S = 30.0
#: Seconds a sweep on a Dask scheduler may go with none of its tasks running on a worker and none
#: finishing (every worker gone, or none ever came) before it stops with an error.
DEFAULT_STALL_TIMEOUT_S = 120.0


@dataclass(frozen=True)
class DaskSettings:
    """How a sweep talks to an existing Dask scheduler (``dask://`` or ``tls://``).

    Attributes:
        connect_timeout_s: seconds to wait for the scheduler's answer (connect and handshake).
        stall_timeout_s: seconds with no task of the sweep running on a worker and none
            finishing, after which the sweep stops with :class:`DaskUnavailable`.
        tls_ca_file: CA certificate(s) (PEM) that the scheduler's certificate must be signed by;
            None: Dask's configuration ``distributed.comm.tls.ca-file``.
        tls_cert: this client's certificate (PEM); None: ``distributed.comm.tls.client.cert``.
        tls_key: this client's private key (PEM); None: ``distributed.comm.tls.client.key`` (or
            the key appended to the certificate file).
    """

    connect_timeout_s: float = DEFAULT_CONNECT_TIMEOUT_S
    stall_timeout_s: float = DEFAULT_STALL_TIMEOUT_S
    tls_ca_file: str | None = None
    tls_cert: str | None = None
    tls_key: str | None = None

    def __post_init__(self) -> None:
        for name in ("connect_timeout_s", "stall_timeout_s"):
            v = getattr(self, name)
            if not (v > 0 and v != float("inf")):
                raise ValueError(f"{name} = {v!r}: must be a positive finite number of seconds")


class DaskUnavailable(ConnectionError):
    """The Dask scheduler did not answer, is not a Dask scheduler, or ran none of the sweep's
    tasks for too long (one line naming its address)."""


@dataclass(frozen=True)
class ExecutorSpec:
    """A parsed ``--executor`` value.

    Attributes:
        kind: ``"serial" | "process" | "dask-local" | "dask"``.
        workers: number of local workers (process pool or LocalCluster).
        address: scheduler address for ``kind == "dask"`` (``tcp://HOST:PORT`` or
            ``tls://HOST:PORT``).
        dask: timeouts and certificates for ``kind == "dask"``; None: :class:`DaskSettings`
            defaults, certificates from Dask's configuration.
    """

    kind: str
    workers: int = 1
    address: str = ""
    dask: DaskSettings | None = None


def default_workers() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - non-Linux
        return max(1, os.cpu_count() or 1)


def parse_executor(text: str) -> ExecutorSpec:
    """Parse ``serial``, ``process[:N]``, ``dask-local[:N]``, ``dask://HOST:PORT`` or
    ``tls://HOST:PORT``.

    Raises:
        ValueError: ``text`` names no known executor, a ``dask://`` or ``tls://`` address
            without ``HOST:PORT``, a worker count for ``serial`` or a worker count that is not a
            positive integer.
    """
    text = text.strip()
    for scheme, protocol in (("dask://", "tcp"), ("tls://", "tls")):
        if text.startswith(scheme):
            host, sep, port = text[len(scheme):].rpartition(":")
            if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
                raise ValueError(f"--executor {text!r}: expected {scheme}HOST:PORT")
            return ExecutorSpec("dask", address=f"{protocol}://{host}:{port}")
    name, sep, count = text.partition(":")
    if name not in ("serial", "process", "dask-local"):
        raise ValueError(f"--executor {text!r}: expected one of {', '.join(EXECUTORS)}")
    if name == "serial":
        if sep:
            raise ValueError(f"--executor {text!r}: 'serial' takes no worker count")
        return ExecutorSpec("serial", workers=1)
    if sep:
        if not count.isdigit() or int(count) < 1:
            raise ValueError(f"--executor {text!r}: worker count must be a positive integer")
        workers = int(count)
    else:
        workers = default_workers()
    return ExecutorSpec(name, workers=workers)


def resolve_executor(executor: str | None, workers: int | None) -> str:
    """``executor`` if given (``workers`` is then not read), else ``process:<workers>``, else
    ``process`` (every core).

    Raises:
        AnalysisError: an executor spec that does not parse (:func:`parse_executor`).
    """
    if executor is None:
        executor = "process" if workers is None else f"process:{max(1, int(workers))}"
    try:
        parse_executor(executor)
    except ValueError as e:
        raise AnalysisError(str(e)) from None
    return executor
