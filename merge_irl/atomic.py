"""Atomic file writes, the project's only ones: a complete temporary file in the target folder,
then a rename.

A crash or Ctrl-C mid-write never leaves a truncated file under the final name: the previous
complete file, no file, or a hidden ``.NAME.<random>.tmp<suffix>`` file remains. Files are
created with mode ``0666`` minus the process umask (``0644`` under the usual umask ``022``),
as ``open()`` and pandas' Parquet writer create them; ``tempfile.mkstemp`` would leave ``0600``.

Every writer of the project goes through :func:`write_atomic` (Parquet tables, JSON, Markdown,
TOML, NPZ, PNG plots) or, for streams that stay open across calls (rerun recordings), through
:func:`temporary_path` + :func:`move_into_place`.
"""

from __future__ import annotations

import json
import os
import secrets
from collections.abc import Callable
from pathlib import Path
from typing import Any


def temporary_path(path: str | os.PathLike, suffix: str | None = None) -> Path:
    """Create an empty hidden temporary file beside ``path`` and return its path.

    Its name ends with ``path``'s suffix (writers that infer the format from it, such as
    matplotlib's ``savefig``, see the right one). The parent folder is created if needed.

    Args:
        path: the final file name.
        suffix: another ending for the temporary name (default: ``path``'s suffix), e.g. so
            that a file being streamed is not found by a glob for finished ones.

    Raises:
        OSError: if the folder cannot be created or written.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    while True:
        tmp = path.with_name(f".{path.name}.{secrets.token_hex(4)}.tmp{path.suffix if suffix is None else suffix}")
        try:
            # O_EXCL: a fresh name; mode 0o666 is reduced by the umask like any new file.
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
            return tmp
        except FileExistsError:
            continue


def move_into_place(tmp: str | os.PathLike, path: str | os.PathLike) -> Path:
    """Move the finished ``tmp`` (from :func:`temporary_path`) to ``path`` in one rename.

    Raises:
        OSError: if the rename fails (``tmp`` is then removed).
    """
    try:
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return Path(path)


def write_atomic(path: str | os.PathLike, write: Callable[[Path], object]) -> Path:
    """Create ``path`` by calling ``write(tmp_path)`` on a temporary file, then renaming it.

    ``write`` receives the temporary file's path (it exists, empty) and writes the whole
    content there, e.g. ``lambda p: table.to_parquet(p, index=False)``. On any error the
    temporary file is removed, the error re-raised, and an existing file at ``path`` is left
    untouched.

    Args:
        path: the final file name; its folder is created if needed.
        write: writes the content to the path it is given.

    Returns:
        ``path`` as a :class:`~pathlib.Path`.

    Raises:
        OSError: if the folder or file cannot be written (naming ``path`` when the error named
            no file, e.g. a full disk); whatever else ``write`` raises.
    """
    tmp = temporary_path(path)
    try:
        write(tmp)
    except OSError as e:
        tmp.unlink(missing_ok=True)
        if e.filename is None:  # a write() or a library's writer (pyarrow) names no file: name it
            raise with_path(e, path) from e
        raise
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return move_into_place(tmp, path)


def with_path(e: OSError, path: str | os.PathLike) -> OSError:
    """``e`` as an :class:`OSError` of the same errno naming ``path`` (e.g. ``No space left on
    device: /runs/x/trajectories.parquet`` for a full disk)."""
    message = os.strerror(e.errno) if isinstance(e.errno, int) else (str(e) or type(e).__name__)
    return OSError(e.errno, message, str(path))


def write_text_atomic(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically (see :func:`write_atomic`)."""
    return write_atomic(path, lambda p: p.write_text(text, encoding="utf-8"))


def write_json_atomic(path: str | os.PathLike, data: Any, *, indent: int | None = 1) -> Path:
    """Write ``data`` as JSON to ``path`` atomically (see :func:`write_atomic`)."""
    return write_text_atomic(path, json.dumps(data, indent=indent))
