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
import contextlib
import os
import threading
import time
import uuid
from collections.abc import Callable, Sequence
from typing import Any

from analysis.sweep.executors import DEFAULT_STALL_TIMEOUT_S, DaskSettings, DaskUnavailable, ExecutorSpec
from merge_irl.cancel import cancellable

#: Dask configuration key of :attr:`DaskSettings.stall_timeout_s` (a number of seconds or a
#: duration such as ``"5m"``); environment variable ``DASK_MERGE_IRL__STALL_TIMEOUT``.
STALL_TIMEOUT_KEY = "merge-irl.stall-timeout"
#: Seconds between two looks at the scheduler for the stall check.
POLL_S = 0.25
#: Seconds that Ctrl-C waits for the sweep's tasks running on workers to stop (they poll the
#: sweep's stop event between SUMO steps and before publishing, :mod:`merge_irl.cancel`); runs
#: that finished meanwhile are recorded, the rest cancelled.
STOP_WAIT_S = 10.0
#: Seconds to wait for the scheduler's answer to each of Ctrl-C's requests.
ASK_TIMEOUT_S = 5.0


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
        check_tls_files(address, security, settings)
    return security


#: Each TLS file of :class:`distributed.security.Security`: its option and Dask's configuration key.
_TLS_FILES = (("tls_ca_file", "tls_ca_file", "--dask-tls-ca-file", "distributed.comm.tls.ca-file"),
              ("tls_client_cert", "tls_cert", "--dask-tls-cert", "distributed.comm.tls.client.cert"),
              ("tls_client_key", "tls_key", "--dask-tls-key", "distributed.comm.tls.client.key"))


def check_tls_files(address: str, security, settings: DaskSettings) -> None:
    """Load the CA file, the client's certificate and its key as the TLS handshake will, before
    connecting, so that a missing or unreadable file and a key that is not the certificate's are
    named as such (instead of a handshake failure blamed on the scheduler).

    Raises:
        DaskUnavailable: a file is missing, is no PEM certificate (CA, certificate) or key, or
            the key does not match the certificate (one line naming the files and options).
    """
    import ssl

    where = f"Dask scheduler {address}: TLS"
    named: dict[str, str] = {}
    for field, given, option, config_key in _TLS_FILES:
        path = getattr(security, field, None)
        if not path:
            continue
        named[field] = f"{path} ({option if getattr(settings, given) else option + ' / ' + config_key})"
        if not os.path.isfile(path):
            raise DaskUnavailable(f"{where}: {named[field]}: no such file")
    ctx = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
    for field in ("tls_ca_file", "tls_client_cert"):
        if field in named:
            try:
                ctx.load_verify_locations(cafile=getattr(security, field))
            except (ssl.SSLError, ValueError, UnicodeDecodeError) as e:
                raise DaskUnavailable(f"{where}: {named[field]}: not a PEM certificate ({_ssl_reason(e)})") from None
    cert, key = security.tls_client_cert, getattr(security, "tls_client_key", None)
    try:
        ctx.load_cert_chain(cert, key)
    except ssl.SSLError as e:
        raise DaskUnavailable(_key_problem(where, e, named)) from None


def _key_problem(where: str, e: BaseException, named: dict[str, str]) -> str:
    """The line for a client certificate and key that :meth:`ssl.SSLContext.load_cert_chain` refused."""
    cert = named["tls_client_cert"]
    key = named.get("tls_client_key")
    if "KEY_VALUES_MISMATCH" in str(e) or "key values mismatch" in str(e):
        return f"{where}: the key {key or '(appended to the certificate)'} does not match the certificate {cert}"
    if key is None:
        return (f"{where}: no private key in the certificate file {cert} and no --dask-tls-key "
                f"({_ssl_reason(e)})")
    return f"{where}: the key {key} is not a PEM private key ({_ssl_reason(e)})"


def _ssl_reason(e: BaseException) -> str:
    return str(getattr(e, "reason", None) or _one_line(e))


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
    except Exception as e:  # noqa: BLE001 - each named by _connect_problem
        raise DaskUnavailable(_connect_problem(e, address, settings, security)) from None
    if not isinstance(info, dict) or info.get("type") != "Scheduler":
        raise DaskUnavailable(f"{where}: what answers is not a Dask scheduler ({str(info)[:100]})")


def _connect_problem(e: BaseException, address: str, settings: DaskSettings, security) -> str:
    """The line for a failed first contact with ``address``: a protocol mismatch (TLS against
    plain TCP or the reverse, :func:`protocol_mismatch`), no answer in time, a refused or broken
    connection, a failed TLS handshake (:func:`tls_problem`) or another protocol."""
    where = f"Dask scheduler {address}"
    mismatch = protocol_mismatch(address, min(settings.connect_timeout_s, PROBE_TIMEOUT_S))
    if mismatch:
        return mismatch
    if isinstance(e, TimeoutError):
        return (f"{where}: no answer within {settings.connect_timeout_s:g} s (--dask-connect-timeout); is a Dask "
                "scheduler listening there?")
    if isinstance(e, OSError):  # refused (after retries until the timeout), reset, TLS handshake
        tls = tls_problem(e, address, security)
        return f"{where}: {tls}" if tls else f"{where}: not reachable ({_one_line(e)})"
    # a reply in another protocol (HTTP read as a frame size: MemoryError)
    return (f"{where}: what answers does not speak Dask's protocol (a web server or another service on that "
            f"port?): {_one_line(e)}")


#: Seconds (at most) of each look, after a failed contact, for the other protocol on the port.
PROBE_TIMEOUT_S = 3.0


def protocol_mismatch(address: str, timeout_s: float) -> str:
    """After a failed contact: ``""``, or the line saying that ``address`` is asked in the wrong
    protocol: a ``tls://`` address where a Dask scheduler answers in plain TCP, or a ``tcp://``
    address where the peer answers a TLS handshake (certificates unchecked: only whether it
    speaks TLS)."""
    scheme, _, rest = address.partition("://")
    host, _, port = rest.rpartition(":")
    if scheme == "tls" and _answers_plain_dask(f"tcp://{rest}", timeout_s):
        return (f"Dask scheduler at {address} does not speak TLS: it answers in plain TCP; use --executor "
                f"dask://{rest} (a network you trust only), or start the scheduler with --protocol tls")
    if scheme == "tcp" and _speaks_tls(host.strip("[]"), int(port), timeout_s):
        return (f"Dask scheduler at {address} speaks TLS, not plain TCP: use --executor tls://{rest} with its "
                "certificates (--dask-tls-ca-file, --dask-tls-cert, --dask-tls-key)")
    return ""


def _answers_plain_dask(address: str, timeout_s: float) -> bool:
    """Whether a Dask scheduler answers at the plain ``tcp://`` ``address`` within ``timeout_s``."""
    from distributed.core import rpc

    async def identity() -> Any:
        r = rpc(address, timeout=timeout_s)
        try:
            return await r.identity()
        finally:
            await r.close_rpc()

    try:
        info = _run(lambda: asyncio.wait_for(identity(), timeout_s))
    except Exception:  # noqa: BLE001 - no plain Dask there
        return False
    return isinstance(info, dict) and info.get("type") == "Scheduler"


def _speaks_tls(host: str, port: int, timeout_s: float) -> bool:
    """Whether the peer at ``host:port`` completes a TLS handshake or answers it with a TLS alert
    (its certificate is not checked: this only tells the protocol)."""
    import socket
    import ssl

    ctx = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
    ctx.check_hostname = False
    ctx.verify_mode = ssl.CERT_NONE
    try:
        with socket.create_connection((host, port), timeout=timeout_s) as raw, \
                ctx.wrap_socket(raw, server_hostname=host):
            return True
    except ssl.SSLError as e:
        return "alert" in str(e).lower()
    except OSError:  # refused, reset, no answer in time
        return False


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
    if not todo:  # every task stored: no scheduler needed (none is asked, no cluster started)
        return
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
    stop_name = f"merge-irl-stop-{uuid.uuid4().hex}"  # the sweep's stop event (call_stoppable)

    def submit(p):
        # Dask itself reschedules a task whose worker died (up to its allowed-failures);
        # an exception or KilledWorker comes back here and is retried once like elsewhere.
        key = f"{p.task.key}-{p.digest[:12]}-{p.attempts}"
        fut = client.submit(call_stoppable, call_task, p.task.func, p.task.config, p.seed, stop_name, key=key,
                            pure=False)
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
    except BaseException as e:
        if pending:
            gone = isinstance(e, DaskUnavailable) and "went away" in str(e)
            stop_in_flight(client, stop_name, pending, lambda key, record: finish(futures[key], record),
                           wait_s=STOP_WAIT_S if isinstance(e, KeyboardInterrupt) else 0.0, ask=not gone)
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


def call_stoppable(call_task: Callable, func: Callable, config: Any, seed: int, stop_name: str) -> dict[str, Any]:
    """On a Dask worker: ``call_task(func, config, seed)`` that stops once its sweep is stopped.

    The task polls (:func:`merge_irl.cancel.cancellable`) whether the sweep's Dask ``Event``
    ``stop_name`` is set (Ctrl-C in the client) or the scheduler has released this task (the
    client cancelled it or went away); a SUMO run then stops between two steps and publishes
    nothing, and its record says ``Cancelled``. A worker thread cannot be killed from outside:
    this is how a cancelled run ends instead of publishing its folder after the client exited.
    """
    stop = _stop_check(stop_name)
    if stop():
        return {"ok": False, "error": "Cancelled: the sweep was stopped before this task started",
                "retry": False, "wall_time_s": 0.0}
    with cancellable(stop):
        return call_task(func, config, seed)


def _stop_check(stop_name: str) -> Callable[[], bool]:
    """Whether this worker task should stop: the sweep's stop event set, or the task released."""
    from distributed import get_client, get_worker
    from distributed.worker import thread_state

    key = getattr(thread_state, "key", None)
    try:
        worker = get_worker()
    except ValueError:  # not on a worker (a test calling it directly)
        worker = None

    def stop() -> bool:
        if worker is not None and key is not None:
            ts = worker.state.tasks.get(key)
            if ts is None or ts.state == "cancelled":
                return True
        try:
            client = get_client()
            scheduler = client.scheduler
            return scheduler is not None and bool(
                client.sync(scheduler.event_is_set, name=stop_name, callback_timeout=ASK_TIMEOUT_S))
        except Exception:  # noqa: BLE001 - the scheduler unreachable for now: go on (released tasks stop above)
            return False

    return stop


def stop_in_flight(client, stop_name: str, pending: dict[str, Any], record: Callable[[str, dict], Any], *,
                   wait_s: float, ask: bool = True) -> None:
    """Stop the sweep's unfinished tasks ``pending`` (key -> future): set its stop event (the
    tasks running notice it, :func:`call_stoppable`), cancel those not yet on a worker, wait up
    to ``wait_s`` s for the running ones to end, hand each that finished meanwhile to
    ``record(key, record)`` (so that a run published meanwhile is recorded), and cancel the rest.
    ``ask``: False when the scheduler is gone (nothing is asked of it)."""
    from distributed import wait

    try:
        if ask:
            with contextlib.suppress(Exception):
                client.sync(client.scheduler.event_set, name=stop_name, callback_timeout=ASK_TIMEOUT_S)
            running = set()
            with contextlib.suppress(Exception):
                processing = client.sync(client.scheduler.processing, workers=None, callback_timeout=ASK_TIMEOUT_S)
                running = {str(k) for keys in processing.values() for k in keys} & set(pending)
            with contextlib.suppress(Exception):
                client.cancel([f for k, f in pending.items() if k not in running], force=True)
            if running and wait_s > 0:
                with contextlib.suppress(Exception):  # distributed's TimeoutError
                    wait([pending[k] for k in running], timeout=wait_s)
        for key, fut in list(pending.items()):
            if fut.status == "finished":
                result = fut.result()
                if isinstance(result, dict) and result.get("ok"):
                    record(key, result)
    finally:
        with contextlib.suppress(Exception):
            client.cancel(list(pending.values()), force=True)
