"""Reading ``.rrd`` recordings back for scripted inspection and tests (rerun's ``RrdReader``).

:func:`read_rrd_table` gives a pandas table of a recording's rows, :func:`read_blueprint` the
views of the layout shipped with it (:func:`analysis.recording.blueprint.merge_blueprint`),
:func:`recording_info` its ids and name, :func:`read_entities` the raw arrow batches,
:func:`check_rrd` whether the file reads at all. rerun is
imported inside the functions: it takes about 0.8 s to import.
"""

from __future__ import annotations

import os
from pathlib import Path

import pyarrow as pa

from analysis.recording.files import PROPERTIES


def read_entities(path: str | os.PathLike) -> dict[str, list]:
    """Entity path -> list of pyarrow record batches of an ``.rrd`` (for tests and checks)."""
    from rerun.chunk import RrdReader

    out: dict[str, list] = {}
    for chunk in RrdReader(str(path)).store().stream():
        out.setdefault(chunk.entity_path, []).append(chunk.to_record_batch())
    return out


def _open_rrd(path: str | os.PathLike):
    """A ``rerun.chunk.RrdReader`` of ``path``; FileNotFoundError naming it when it is missing."""
    from rerun.chunk import RrdReader  # rerun takes about 0.8 s to import

    if not Path(path).is_file():
        raise FileNotFoundError(f"{path}: no such recording")
    return RrdReader(str(path))


def check_rrd(path: str | os.PathLike) -> int:
    """Read every chunk of every store of an ``.rrd`` once, as the viewer would; returns the
    number of chunks read. Cheap for the recordings this project writes (a few MB: tens of ms).

    Raises:
        FileNotFoundError: no such file.
        ValueError: the file is not a readable rerun recording (not an ``.rrd`` at all, cut
            short, or corrupt), in one line naming it and rerun's reason.
    """
    import warnings

    try:
        with warnings.catch_warnings():  # rerun warns about files without a footer; the error says more
            warnings.simplefilter("ignore")
            reader = _open_rrd(path)
            stores = [*reader.recordings(), *reader.blueprints()]
            if not stores:
                raise ValueError("no recording in it")
            return sum(1 for store in stores for _ in reader.stream(store=store))
    except FileNotFoundError:
        raise
    except (RuntimeError, ValueError, OSError) as e:
        reason = " ".join(str(e).split())
        prefix = f"Failed to read RRD file at {path}: "
        reason = reason[len(prefix):] if reason.startswith(prefix) else reason
        raise ValueError(f"{path}: not a readable rerun recording ({reason})") from None


def read_blueprint(path: str | os.PathLike) -> list[dict]:
    """The views of the blueprint stored in an ``.rrd``: one dict per view, ``{"name",
    "kind"`` (e.g. ``"2D"``, ``"TimeSeries"``, ``"BarChart"``), ``"origin"``, ``"contents"``
    (the entity filter lines)``}``, in no particular order.

    Raises:
        FileNotFoundError: no such file.
        ValueError: the file holds no blueprint.
    """
    reader = _open_rrd(path)
    entries = reader.blueprints()
    if not entries:
        raise ValueError(f"{path}: no blueprint in this .rrd file")
    views: dict[str, dict] = {}
    for chunk in reader.stream(store=entries[-1]):
        ent = chunk.entity_path
        if not ent.startswith("/view/"):
            continue
        key = ent.split("/")[2]
        v = views.setdefault(key, {"name": None, "kind": None, "origin": None, "contents": []})
        batch = chunk.to_record_batch().to_pydict()
        for col, field in (("ViewBlueprint:display_name", "name"), ("ViewBlueprint:class_identifier", "kind"),
                           ("ViewBlueprint:space_origin", "origin")):
            if col in batch and batch[col] and batch[col][-1]:
                v[field] = batch[col][-1][0]
        if batch.get("ViewContents:query"):
            v["contents"] = list(batch["ViewContents:query"][-1] or [])
    return list(views.values())


def recording_info(path: str | os.PathLike) -> dict[str, str | None]:
    """``{"application_id", "recording_id", "name"}`` of the (first) recording in an ``.rrd``
    (``name`` None if none was set).

    Raises:
        FileNotFoundError: no such file.
        ValueError: the file holds no recording.
    """
    reader = _open_rrd(path)
    entries = reader.recordings()
    if not entries:
        raise ValueError(f"{path}: no recording in this .rrd file")
    name = None
    for chunk in reader.stream(store=entries[0]):
        if chunk.entity_path == PROPERTIES:
            batch = chunk.to_record_batch()
            if "RecordingInfo:name" in batch.schema.names:
                name = str(batch.column("RecordingInfo:name")[0][0])
    return {"application_id": entries[0].application_id, "recording_id": entries[0].recording_id, "name": name}


def _batch_frame(batch):
    """A record batch as pandas; columns pandas cannot hold (e.g. ``BarChart``'s tensor
    unions) as Python objects."""
    import pandas as pd

    try:
        return batch.to_pandas()
    except (pa.ArrowNotImplementedError, pa.ArrowTypeError):
        cols = {}
        for name, col in zip(batch.schema.names, batch.columns):
            try:
                cols[name] = pa.table({name: col}).to_pandas()[name]
            except (pa.ArrowNotImplementedError, pa.ArrowTypeError):
                cols[name] = pd.Series(col.to_pylist(), dtype=object)
        return pd.DataFrame(cols)


def read_rrd_table(path: str | os.PathLike, entity: str | None = None, *, properties: bool = False):
    """An ``.rrd`` file as a pandas table, one row per logged row, in file order.

    Columns: ``entity`` (e.g. ``/metrics/A_12/speed``), ``static``, one column per timeline
    present (``step``, ``iteration``: integers; ``sim_time``: float seconds; NaN/None where an
    entity lacks it) and one per component (rerun's names, e.g. ``Scalars:scalars``,
    ``Boxes3D:centers``, ``vehicle_id``). A component column whose every value is a
    one-element list holds that element; others hold arrays (e.g. the 5 action probabilities
    of ``policy/A_<id>/probs``, or one array per frame of ``world/vehicles``).

    Example::

        df = read_rrd_table("runs/eval/rerun/qavg.rrd", "/metrics/")
        speed = df[df.entity.str.endswith("/speed")][["entity", "sim_time", "Scalars:scalars"]]

    Args:
        entity: keep only entities whose path starts with this (None: all).
        properties: also return the recording's properties (``/__properties``: name, start time).

    Raises:
        FileNotFoundError: no such file.
        ValueError: the file holds no recording.
    """
    import pandas as pd
    reader = _open_rrd(path)
    if not reader.recordings():
        raise ValueError(f"{path}: no recording in this .rrd file")
    parts = []
    for chunk in reader.stream():
        ent = chunk.entity_path
        if (entity is not None and not ent.startswith(entity)) or (ent == PROPERTIES and not properties):
            continue
        batch = chunk.to_record_batch()
        keep = [f.name for f in batch.schema if (f.metadata or {}).get(b"rerun:kind") != b"control"]
        df = _batch_frame(batch.select(keep))
        for col in df.columns:
            if pd.api.types.is_timedelta64_dtype(df[col]):
                df[col] = df[col].dt.total_seconds()
        df.insert(0, "static", bool(chunk.is_static))
        df.insert(0, "entity", ent)
        parts.append(df)
    if not parts:
        return pd.DataFrame({"entity": pd.Series(dtype=object), "static": pd.Series(dtype=bool)})
    table = pd.concat(parts, ignore_index=True)
    for col in table.columns[2:]:
        values = table[col].dropna()
        if len(values) and all(hasattr(v, "__len__") and not isinstance(v, str) and len(v) == 1 for v in values):
            table[col] = [v[0] if hasattr(v, "__len__") and not isinstance(v, str) else v for v in table[col]]
    return table
