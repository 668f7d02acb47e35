"""The Dask executors: a sweep's tasks on a ``LocalCluster`` or an existing scheduler.

An existing scheduler (``dask://HOST:PORT``, ``tls://HOST:PORT``) is first asked who it is, with
a deadline (:attr:`DaskSettings.connect_timeout_s`): a port where nothing answers, a plain TCP
listener that never replies and a web server that replies with HTTP all end in one
:class:`DaskUnavailable` line naming the address, instead of a wait without end or Dask's
traceback. While the tasks run, a sweep with none of its tasks running on a worker and none
finishing for :attr:`DaskSettings.stall_timeout_s` (its only worker died, no nanny restarted it)
stops with the same error. Ctrl-C cancels the sweep's tasks on the scheduler.

Settings not given come from Dask's configuration (files, ``DASK_*`` environment variables, or
``dask.config.set``): ``distributed.comm.timeouts.connect``, ``merge-irl.stall-timeout`` and the
certificates ``distributed.comm.tls.ca-file``, ``distributed.comm.tls.client.cert`` and
``distributed.comm.tls.client.key`` (:class:`distributed.security.Security`).
"""

from __future__ import annotations

import asyncio
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

from analysis.sweep.executors import DEFAULT_STALL_TIMEOUT_S, DaskSettings, DaskUnavailable, ExecutorSpec

#: Dask configuration key of :attr:`DaskSettings.stall_timeout_s` (a number of seconds or a
#: duration such as ``"5m"``); environment variable ``DASK_MERGE_IRL__STALL_TIMEOUT``.
STALL_TIMEOUT_KEY = "merge-irl.stall-timeout"
#: Seconds between two looks at the scheduler for the stall check.
POLL_S = 0.25


def settings_from_config() -> DaskSettings:
    """:class:`DaskSettings` from Dask's configuration (certificates left to
    :class:`distributed.security.Security`, which reads them itself)."""
    import dask.config
    from dask.utils import parse_timedelta

    connect = parse_timedelta(dask.config.get("distributed.comm.timeouts.connect"), default="seconds")
    stall = parse_timedelta(dask.config.get(STALL_TIMEOUT_KEY, DEFAULT_STALL_TIMEOUT_S), default="seconds")
    return DaskSettings(connect_timeout_s=float(connect), stall_timeout_s=float(stall))


def security_for(address: str, settings: DaskSettings):
    """The client's :class:`distributed.security.Security`: the files of ``settings``, else
    Dask's configuration.

    Raises:
        DaskUnavailable: a ``tls://`` address and no CA file or no client certificate anywhere.
    """
    from distributed.security import Security

    given = {k: v for k, v in (("tls_ca_file", settings.tls_ca_file), ("tls_client_cert", settings.tls_cert),
                               ("tls_client_key", settings.tls_key)) if v}
    security = Security(**given) if given else Security()
    if address.startswith("tls://"):
        missing = [opt for opt, field in (("--dask-tls-ca-file", "tls_ca_file"), ("--dask-tls-cert", "tls_client_cert"))
                   if not getattr(security, field, None)]
        if missing:
            raise DaskUnavailable(
                f"Dask scheduler {address}: TLS needs {' and '.join(missing)} (or Dask's configuration "
                "distributed.comm.tls.ca-file / distributed.comm.tls.client.cert)")
    return security


def check_scheduler(address: str, settings: DaskSettings, security) -> None:
    """Ask ``address`` who it is; return if a Dask scheduler answers within the connect timeout.

    Raises:
        DaskUnavailable: nothing answers in time, the connection is refused or broken, the
            TLS handshake fails (which side refused which file: :func:`tls_problem`), or what
            answers is not a Dask scheduler.
    """
    from distributed.core import rpc

    async def identity() -> Any:
        r = rpc(address, timeout=settings.connect_timeout_s,
                connection_args=security.get_connection_args("client"))
        try:
            return await r.identity()
        finally:
            await r.close_rpc()

    where = f"Dask scheduler {address}"
    try:
        info = _run(lambda: asyncio.wait_for(identity(), settings.connect_timeout_s))
    except TimeoutError:
        raise DaskUnavailable(f"{where}: no answer within {settings.connect_timeout_s:g} s "
                              "(--dask-connect-timeout); is a Dask scheduler listening there?") from None
    except OSError as e:  # refused (after retries until the timeout), reset, TLS handshake
        tls = tls_problem(e, address, security)
        raise DaskUnavailable(f"{where}: {tls}" if tls else f"{where}: not reachable ({_one_line(e)})") from None
    except Exception as e:  # noqa: BLE001 - a reply in another protocol (HTTP read as a frame size: MemoryError)
        raise DaskUnavailable(f"{where}: what answers does not speak Dask's protocol (a web server or another "
                              f"service on that port?): {_one_line(e)}") from None
    if not isinstance(info, dict) or info.get("type") != "Scheduler":
        raise DaskUnavailable(f"{where}: what answers is not a Dask scheduler ({str(info)[:100]})")


def tls_problem(e: BaseException, address: str, security) -> str:
    """What a failed TLS handshake with ``address`` says, naming the side that refused and the file
    at stake, or ``""`` when ``e`` (an exception and its causes) is no TLS failure:

    * this client refused the scheduler's certificate (``ssl.SSLCertVerificationError``: signed by
      another authority than the CA file's, expired, for another host): the CA file is named;
    * the scheduler ended the handshake (an EOF or reset during it, a TLS alert): it refused this
      client's certificate (not signed by the scheduler's CA, or expired): the certificate is named.
    """
    import ssl

    if not address.startswith("tls://"):
        return ""
    ca = getattr(security, "tls_ca_file", None) or "(Dask's configured CA)"
    cert = getattr(security, "tls_client_cert", None) or "(Dask's configured client certificate)"
    seen: set[int] = set()
    err: BaseException | None = e
    while err is not None and id(err) not in seen:
        seen.add(id(err))
        if isinstance(err, ssl.SSLCertVerificationError):
            why = err.verify_message or _one_line(err)
            return (f"TLS: this client refused the scheduler's certificate ({why}): it does not verify against the "
                    f"CA file {ca} (--dask-tls-ca-file); give the CA that signed the scheduler's certificate, or "
                    "renew an expired one")
        if isinstance(err, (ssl.SSLEOFError, ssl.SSLZeroReturnError)) or (
                isinstance(err, ssl.SSLError) and "alert" in str(err).lower()):
            return (f"TLS: the scheduler ended the handshake ({_one_line(err)}): it refused this client's certificate "
                    f"{cert} (--dask-tls-cert): not signed by the scheduler's CA, or expired")
        err = err.__cause__ or err.__context__
    if "before comm was established" in str(e):
        # under load Dask reports the scheduler closing the TLS handshake without its SSL cause
        return (f"TLS: the scheduler ended the handshake ({_one_line(e)}): it refused this client's certificate "
                f"{cert} (--dask-tls-cert): not signed by the scheduler's CA, or expired")
    return ""


def _run(make: Callable[[], Any]) -> Any:
    """Run the coroutine ``make()`` to its end; in a thread of its own when this thread already
    runs an event loop (a notebook), where :func:`asyncio.run` is refused."""
    try:
        asyncio.get_running_loop()
    except RuntimeError:
        return asyncio.run(make())
    box: dict[str, Any] = {}

    def target() -> None:
        try:
            box["value"] = asyncio.run(make())
        except BaseException as e:  # noqa: BLE001 - handed to the caller
            box["error"] = e

    thread = threading.Thread(target=target, name="dask-scheduler-check", daemon=True)
    thread.start()
    thread.join()
    if "error" in box:
        raise box["error"]
    return box.get("value")


def _one_line(e: BaseException) -> str:
    text = " ".join(str(e).split())
    return f"{type(e).__name__}: {text[:200]}" if text else type(e).__name__


def run_dask(todo: Sequence[Any], finish: Callable[[Any, dict], bool], spec: ExecutorSpec,
             call_task: Callable, crash_record: Callable[[BaseException], dict]) -> None:
    """Run the pending tasks ``todo`` (``analysis.sweep.sweep._Pending``) on Dask; ``finish``
    records each attempt and says whether to retry it.

    Raises:
        RuntimeError: Dask distributed is not installed.
        DaskUnavailable: see :func:`check_scheduler`, the sweep stalled (module docstring), or
            the scheduler went away mid-sweep (:func:`scheduler_gone`; the tasks finished until
            then have been handed to ``finish``, so a store keeps them).
        KeyboardInterrupt: Ctrl-C; the sweep's tasks are cancelled on the scheduler.
    """
    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError as e:  # pragma: no cover - depends on the install
        raise RuntimeError("the dask executors need Dask distributed: pip install 'merge-irl[dask]'") from e
    cluster = None
    settings = spec.dask or settings_from_config()
    if spec.kind == "dask-local":
        cluster = LocalCluster(n_workers=spec.workers, threads_per_worker=1, processes=True,
                               host="127.0.0.1", dashboard_address=None)
        client = Client(cluster)
    else:
        security = security_for(spec.address, settings)
        check_scheduler(spec.address, settings, security)
        client = Client(spec.address, security=security, timeout=settings.connect_timeout_s)
    futures: dict[str, Any] = {}
    pending: dict[str, Any] = {}
    n_done = [0]  # tasks finished in this call

    def submit(p):
        # Dask itself reschedules a task whose worker died (up to its allowed-failures);
        # an exception or KilledWorker comes back here and is retried once like elsewhere.
        key = f"{p.task.key}-{p.digest[:12]}-{p.attempts}"
        fut = client.submit(call_task, p.task.func, p.task.config, p.seed, key=key, pure=False)
        futures[key] = p
        pending[key] = fut
        return fut

    try:
        ac = as_completed([submit(p) for p in todo])
        last_progress = time.monotonic()
        last_look = 0.0
        while not ac.is_empty():
            batch = ac.next_batch(block=False)
            if batch:
                last_progress = time.monotonic()
            for fut in batch:
                p = futures[fut.key]
                pending.pop(fut.key, None)
                try:
                    record = fut.result()
                except Exception as e:  # noqa: BLE001 - KilledWorker and friends
                    if scheduler_gone(e, client):  # not a worker's death: no retry, no __main__ advice
                        where = spec.address or getattr(cluster, "scheduler_address", "dask-local")
                        raise DaskUnavailable(
                            f"Dask scheduler {where} went away (connection lost) with {len(pending) + 1} of the "
                            f"sweep's {len(todo)} task(s) unfinished; the {n_done[0]} finished here are kept (a "
                            "store keeps them: the same command runs only the rest once a scheduler is back)") from None
                    record = crash_record(e)
                if record.get("ok"):
                    n_done[0] += 1
                if finish(p, record):
                    ac.add(submit(p))
            if batch:
                continue
            now = time.monotonic()
            if now - last_look >= 1.0 and pending:
                last_look = now
                if _any_running(client, pending):
                    last_progress = now
                elif now - last_progress > settings.stall_timeout_s:
                    where = spec.address or getattr(cluster, "scheduler_address", "dask-local")
                    raise DaskUnavailable(
                        f"Dask scheduler {where}: none of this sweep's {len(pending)} unfinished task(s) has "
                        f"run on a worker for {settings.stall_timeout_s:g} s (--dask-stall-timeout); "
                        "are its workers alive?")
            time.sleep(POLL_S)
    except BaseException:
        if pending:
            try:
                client.cancel(list(pending.values()), force=True)
            except Exception:  # noqa: BLE001 - the scheduler may be gone; nothing more to do
                pass
        raise
    finally:
        client.close(timeout=5)
        if cluster is not None:
            cluster.close()


def scheduler_gone(e: BaseException, client) -> bool:
    """Whether a task's failure ``e`` is the scheduler's connection being lost (Dask cancels every
    future with the reason ``scheduler-connection-lost``, or the client has closed), rather than a
    task or worker failure."""
    if "scheduler-connection-lost" in str(e):
        return True
    return type(e).__name__ == "FutureCancelledError" and str(getattr(client, "status", "")) in ("closing", "closed")


def _any_running(client, pending: dict[str, Any]) -> bool:
    """True if a worker is running one of the ``pending`` task keys (Dask's ``processing`` state)."""
    try:
        processing = client.processing()
    except Exception:  # noqa: BLE001 - a scheduler that is reconnecting: count as no progress
        return False
    return any(str(k) in pending for keys in processing.values() for k in keys)
