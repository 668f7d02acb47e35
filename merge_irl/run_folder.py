"""Output folders published as a set: locked, staged in a hidden folder, renamed into place.

A run that writes several files (``merge-irl generate``: trajectories, encounters, merges,
scenario) writes them into a hidden staging folder beside the final one, then publishes the
folder with one rename. Readers see the previous complete set or the new complete set, never a
mix; a run killed at any point publishes nothing under the final name (its staging folder is a
leftover that the next run into the same folder removes).

A lock file beside the folder (``.NAME.lock``, ``fcntl.flock``) keeps two runs from writing
into one folder at once: the second fails at once with :class:`OutputLockedError`. The lock is
released by the kernel when its holder exits, however it ends; its file is removed by a holder
that ends normally (or by Ctrl-C), else by :func:`remove_stale_locks`.

Hidden temporaries of :mod:`merge_irl.atomic` (``.NAME.<8 hex>.tmp<suffix>``) and staging folders
(``.NAME.<8 hex>.tmpdir``) share one naming pattern, :data:`TEMPORARY_NAME`, so that a later
run holding the lock can find and remove those of killed runs (:func:`remove_temporaries`).
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import re
import secrets
import shutil
from collections.abc import Collection, Iterator
from pathlib import Path

from merge_irl.atomic import temporary_path
from merge_irl.cancel import check_cancelled

#: Names of the hidden temporaries of :mod:`merge_irl.atomic` and of staging folders.
TEMPORARY_NAME = re.compile(r"^\..+\.[0-9a-f]{8}\.tmp[^/]*$")


class OutputLockedError(OSError):
    """Another process is writing into the output folder (it holds the folder's lock)."""


def lock_path(folder: str | os.PathLike) -> Path:
    """``.NAME.lock`` beside ``folder`` (outside it, so that the folder can be replaced)."""
    folder = Path(os.path.abspath(folder))  # "." and "a/.." have a name only once resolved
    return folder.parent / f".{folder.name}.lock"


@contextlib.contextmanager
def locked(folder: str | os.PathLike, *, what: str = "folder") -> Iterator[Path]:
    """Hold the exclusive lock of ``folder`` (not created) while the block runs; the lock file
    is removed when the block ends (a holder killed leaves it, free: the kernel releases the
    lock, and :func:`remove_stale_locks` or the next holder removes the file).

    ``what``: ``"folder"``, or ``"file"`` for a single output file (``merge-irl learn``'s
    ``model.json``: its lock is ``.NAME.lock`` beside it); only the message differs.

    Raises:
        OutputLockedError: another process holds it (one line naming the folder).
        OSError: the parent folder cannot be created or written.
    """
    folder = Path(folder)
    lock = lock_path(folder)
    lock.parent.mkdir(parents=True, exist_ok=True)
    fd = _acquire(lock)
    if fd is None:
        target = "into this folder" if what == "folder" else f"this {what}"
        raise OutputLockedError(
            f"{folder}: another run is writing {target} (lock {lock.name} is held); "
            f"wait for it to end or choose another output {what}")
    try:
        yield folder
    finally:
        with contextlib.suppress(OSError):
            lock.unlink()  # while still held: a process waiting on this file sees it gone, retries
        os.close(fd)


def _acquire(lock: Path) -> int | None:
    """Open and ``flock`` ``lock`` without waiting; the descriptor, or None if another process
    holds it. A file removed by its previous holder between our open and our lock is not the
    lock any more: open the path again."""
    while True:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            return None
        except BaseException:
            os.close(fd)
            raise
        try:
            here = os.stat(lock)
        except FileNotFoundError:
            here = None
        mine = os.fstat(fd)
        if here is not None and (here.st_ino, here.st_dev) == (mine.st_ino, mine.st_dev):
            return fd
        os.close(fd)


def remove_stale_locks(folder: str | os.PathLike) -> list[Path]:
    """Remove the lock files (``.NAME.lock``) in ``folder`` that no process holds, left by
    holders that were killed. Returns what was removed."""
    removed: list[Path] = []
    try:
        entries = list(os.scandir(os.fspath(folder)))
    except (FileNotFoundError, NotADirectoryError):
        return removed
    for entry in entries:
        name = str(entry.name)
        if not (name.startswith(".") and name.endswith(".lock") and entry.is_file(follow_symlinks=False)):
            continue
        path = Path(entry.path)
        fd = _acquire(path)
        if fd is None:
            continue  # held: a run in progress
        try:
            path.unlink(missing_ok=True)
            removed.append(path)
        finally:
            os.close(fd)
    return removed


def remove_temporaries(folder: str | os.PathLike, name: str | None = None) -> list[Path]:
    """Remove the hidden temporaries (files and staging folders) of killed runs in ``folder``.

    Call only while holding the lock that covers ``folder``'s writers. ``name``: only those of
    this final name (``.NAME.<hex>.tmp*``). Returns what was removed.
    """
    folder = Path(folder)
    removed: list[Path] = []
    try:
        entries = list(os.scandir(folder))
    except (FileNotFoundError, NotADirectoryError):
        return removed
    for entry in entries:
        if not TEMPORARY_NAME.match(entry.name):
            continue
        if name is not None and not entry.name.startswith(f".{name}."):
            continue
        path = Path(entry.path)
        if entry.is_dir(follow_symlinks=False):
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)
        removed.append(path)
    return removed


def staging_folder(final: str | os.PathLike) -> Path:
    """Create a fresh hidden staging folder ``.NAME.<hex>.tmpdir`` beside ``final``."""
    final = Path(os.path.abspath(final))
    final.parent.mkdir(parents=True, exist_ok=True)
    while True:
        stage = final.with_name(f".{final.name}.{secrets.token_hex(4)}.tmpdir")
        try:
            stage.mkdir()  # mode 0777 minus the umask, like the folders users create
            return stage
        except FileExistsError:
            continue


def check_replaceable(final: str | os.PathLike, own_names: Collection[str]) -> None:
    """Raise unless ``final`` is absent, empty, or holds only files named in ``own_names`` (a
    previous run's set, replaced as a whole when the new set is published).

    Raises:
        NotADirectoryError: ``final`` is a file.
        FileExistsError: ``final`` holds other entries (some named), which publishing would
            remove.
    """
    final = Path(final)
    if not final.exists():
        return
    if not final.is_dir():
        raise NotADirectoryError(f"{final}: exists and is not a folder; expected an output folder")
    foreign = sorted(n for n in os.listdir(final) if n not in own_names and not TEMPORARY_NAME.match(n))
    if foreign:
        shown = ", ".join(foreign[:5]) + (", ..." if len(foreign) > 5 else "")
        raise FileExistsError(
            f"{final}: holds {len(foreign)} entr{'y' if len(foreign) == 1 else 'ies'} that are not "
            f"this run's outputs ({shown}); choose a new or empty output folder")


def publish(stage: str | os.PathLike, final: str | os.PathLike) -> Path:
    """Publish the complete ``stage`` folder as ``final`` in one rename.

    An existing ``final`` (a previous set, see :func:`check_replaceable`) is first renamed to a
    hidden temporary name and removed after the new set is in place, so ``final`` never holds
    a mix of both.

    A run that has been cancelled (:mod:`merge_irl.cancel`: its sweep was interrupted) is asked
    once more here, and publishes nothing.

    Raises:
        OSError: if a rename fails (``final`` then keeps its previous content, or is absent).
        Cancelled: the run was cancelled (``stage`` is left to its caller, as on any error).
    """
    check_cancelled(now=True)
    stage, final = Path(os.path.abspath(stage)), Path(os.path.abspath(final))
    try:
        os.rename(stage, final)  # absent, or an empty folder: replaced in one step
        return final
    except OSError as e:
        if not final.is_dir() or e.errno not in (39, 66):  # ENOTEMPTY (Linux), (BSD)
            raise
    old = final.with_name(f".{final.name}.{secrets.token_hex(4)}.tmpold")
    os.rename(final, old)
    try:
        os.rename(stage, final)
    except BaseException:
        os.rename(old, final)
        raise
    shutil.rmtree(old, ignore_errors=True)
    return final


def check_writable(path: str | os.PathLike) -> Path:
    """Check, before any long work, that a file can be created at ``path`` (its folder is
    created if needed; a test file is created and removed).

    Raises:
        OSError: one naming the path (permission denied, read-only or full file system, a
            parent that is a file, ``path`` an existing folder).
    """
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(21, "Is a directory; expected a file name", str(path))
    tmp = temporary_path(path)
    tmp.unlink()
    return path
