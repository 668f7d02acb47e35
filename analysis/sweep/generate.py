"""Scenario generation over many seeds and demand levels, as one resumable sweep.

``generate_many(spec, seeds, demand_scales, out_dir)`` runs :func:`sim.merges.generate.generate` once
per (seed, demand scale) through :func:`analysis.sweep.run_sweep` (default: a local process
pool on every core, one libsumo simulation per worker process at a time) and writes::

    OUT/<scenario>-seed<N>[-demand<X>]/   trajectories.parquet, encounters.parquet, merges.parquet,
                                          scenario.toml (the spec actually simulated) [, trajectories.csv]
    OUT/.sweep-store/<digest>.json        one record per finished run (what makes reruns skip it)
    OUT/sweep.csv                         one line per finished run (counts, table and scenario
                                          checksums, package/SUMO versions, git commit)
    OUT/sweep.timings.json                each run's wall time (kept out of sweep.csv)
    OUT/sweep.failures.log                the failed runs' tracebacks (``merge-irl generate``, if any)

The ``-demand<X>`` suffix is present when demand scales were given. Each run's SUMO seed is the
one asked for (``seeds``), not the sweep-derived seed, so ``OUT/<scenario>-seed7`` is the same
simulation as ``merge-irl generate --seed 7``. A finished run whose output folder has since lost
a file, or holds another run's files (another duration or encounter rule written into it), is
run again.
"""

from __future__ import annotations

import hashlib
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import pandas as pd

from analysis.sweep import ResultStore, SweepReport, Task, derive_seed, run_sweep, task_digest
from analysis.sweep.store import NOT_IN_DIGEST
from analysis.sweep.sweep import check_executor
from merge_irl.atomic import write_atomic
from merge_irl.cancel import CancelHook
from merge_irl.provenance import provenance, text_digest, write_timings
from merge_irl.run_folder import locked, remove_stale_locks, remove_temporaries
from scenarios.spec.model import ScenarioSpec
from scenarios.spec.parse import spec_from_toml, with_overrides
from sim.merges.generate import RUN_REPORT, SCENARIO, generate
from sim.merges.rules import ENCOUNTER_RULES, check_rule

STORE_DIR = ".sweep-store"
SUMMARY = "sweep.csv"
FAILURES = "sweep.failures.log"  #: the tracebacks of the runs that failed (merge-irl generate)
SWEEP_SEED = 0  #: the runs use their own SUMO seeds; the sweep seed only feeds task digests


@dataclass(frozen=True)
class GenerateRun:
    """One generation task (its full config: the digest of this decides reruns).

    Attributes:
        spec_toml: the base scenario as TOML (before the overrides below).
        seed: SUMO seed of this run.
        demand_scale: factor on every demand flow, or None for the spec's demand.
        duration_s: simulated seconds, or None for the spec's.
        csv: also write ``trajectories.csv``.
        run: the run's folder name inside the sweep folder.
        encounter_rule: how the run becomes demonstrations (:mod:`sim.merges.demonstrators`).
        run_dir: absolute output folder of this run (not part of the digest: a sweep folder
            moved elsewhere still finds its finished runs).
    """

    spec_toml: str
    seed: int
    demand_scale: float | None
    duration_s: float | None
    csv: bool
    run: str
    encounter_rule: str = ENCOUNTER_RULES[0]
    run_dir: str = field(default="", metadata=NOT_IN_DIGEST)


def run_name(scenario: str, seed: int, demand_scale: float | None) -> str:
    """``<scenario>-seed<N>`` or ``<scenario>-seed<N>-demand<X>`` (X printed with ``%g``)."""
    name = f"{scenario}-seed{int(seed)}"
    return name if demand_scale is None else f"{name}-demand{float(demand_scale):g}"


def table_checksum(table: pd.DataFrame) -> str:
    """SHA-256 (hex, 16 chars) of a table's values, column names and dtypes."""
    h = hashlib.sha256()
    h.update(repr([(c, str(t)) for c, t in table.dtypes.items()]).encode())
    h.update(pd.util.hash_pandas_object(table, index=False).to_numpy().tobytes())
    return h.hexdigest()[:16]


def generate_one(config: GenerateRun, seed: int) -> dict:
    """Sweep task: simulate one run and write its folder. ``seed`` (sweep-derived) is unused.

    Returns the run's summary (JSON-ready): name, folder, seed, demand scale, counts, the
    files written (names) and the trajectory table's checksum.
    """
    spec = with_overrides(
        spec_from_toml(config.spec_toml, source="<sweep spec>"), seed=config.seed, duration_s=config.duration_s, demand_scale=config.demand_scale)
    # CancelHook: on a Dask worker, a run whose sweep was interrupted stops between two steps
    res = generate(spec, config.run_dir, csv=config.csv, progress=False, encounter_rule=config.encounter_rule,
                   hooks=(CancelHook(),))
    sim = res.simulation
    return {
        "run": Path(config.run_dir).name,
        "out_dir": str(res.out_dir),
        "seed": int(config.seed),
        "demand_scale": config.demand_scale,
        "n_vehicles": int(sim.n_vehicles),
        "n_rows": int(sim.n_vehicle_steps),
        "n_merges": int(len(res.encounters.merges)),
        "n_encounter_frames": int(len(res.encounters.frames)),
        **{k: sim.events.as_dict()[k] for k in ("requested_veh_h", "served_veh_h", "insertion_backlog", "teleports",
                                                "collisions")},
        "warnings": sim.events.warnings(),
        "files": [p.name for p in res.files],
        "sim_wall_time_s": float(sim.wall_time_s),
        "table_sha256": table_checksum(sim.table),
        "scenario_sha256": text_digest(spec.to_toml()),
    }


def generate_tasks(
    spec: ScenarioSpec,
    seeds: Sequence[int],
    demand_scales: Sequence[float] | None,
    out_dir: str | Path,
    *,
    duration_s: float | None = None,
    csv: bool = False,
    encounter_rule: str = ENCOUNTER_RULES[0],
) -> list[Task]:
    """The sweep's tasks, seeds outermost. Validates every override before anything runs.

    Raises:
        ValueError: no seeds, or an empty ``demand_scales``.
    """
    out = Path(out_dir).resolve()
    if not seeds:
        raise ValueError("generate_many: no seeds given")
    scales: tuple[float | None, ...] = (None,) if demand_scales is None else tuple(demand_scales)
    if not scales:
        raise ValueError("generate_many: empty demand_scales (use None for the spec's demand)")
    text = spec.to_toml()
    tasks = []
    for s in seeds:
        for k in scales:
            with_overrides(spec, seed=s, duration_s=duration_s, demand_scale=k)  # SpecError early
            name = run_name(spec.name, s, k)
            cfg = GenerateRun(spec_toml=text, seed=int(s), demand_scale=None if k is None else float(k),
                              duration_s=None if duration_s is None else float(duration_s), csv=bool(csv),
                              run=name, encounter_rule=encounter_rule, run_dir=str(out / name))
            tasks.append(Task(key=name, func=generate_one, config=cfg))
    return tasks


def _runs_to_do(tasks: Sequence[Task], out: Path) -> bool:
    """Whether some task has no stored record with its outputs in place (read only: nothing is
    created)."""
    if not (out / STORE_DIR).is_dir():
        return True
    store = ResultStore(out / STORE_DIR, create=False)
    for t in tasks:
        record = store.get(task_digest(t.func_name, t.config, derive_seed(SWEEP_SEED, t.key)))
        if record is None or not _outputs_are_the_records(Path(t.config.run_dir), record["result"], t.config):
            return True
    return False


def _forget_missing_outputs(tasks: Sequence[Task], store: ResultStore) -> int:
    """Drop store records whose run folder lost a file or holds another run's files (a sweep
    with another duration or encounter rule wrote into the same folder since), so those runs
    are done again."""
    dropped = 0
    for t in tasks:
        digest = task_digest(t.func_name, t.config, derive_seed(SWEEP_SEED, t.key))
        record = store.get(digest)
        if record is None:
            continue
        if not _outputs_are_the_records(Path(t.config.run_dir), record["result"], t.config):
            store.path(digest).unlink(missing_ok=True)
            dropped += 1
    return dropped


def _outputs_are_the_records(run_dir: Path, result: dict, config: GenerateRun) -> bool:
    """Every file of the record is in ``run_dir``, its ``scenario.toml`` is the one the record
    simulated and its ``run.toml`` names the record's encounter rule."""
    files = result.get("files", [])
    if not files or not all((run_dir / f).is_file() for f in files):
        return False
    try:
        if text_digest((run_dir / SCENARIO).read_text(encoding="utf-8")) != result.get("scenario_sha256"):
            return False
        run = tomllib.loads((run_dir / RUN_REPORT).read_text(encoding="utf-8")).get("run", {})
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return False
    return run.get("encounter_rule") == config.encounter_rule


def write_summary(report: SweepReport, path: str | Path) -> Path:
    """``sweep.csv``: one line per finished run, in task order (atomic write), with the
    provenance of each line: package and SUMO versions, git commit (empty outside a checkout)
    and the SHA-256 of the run's ``scenario.toml``; requested and served flow, the insertion
    backlog, teleports and collisions (SUMO's, see ``run.toml``). The runs' wall times go to
    ``sweep.timings.json`` (:func:`merge_irl.provenance.write_timings`), so that two sweeps'
    ``sweep.csv`` can be compared by hash."""
    cols = ["run", "seed", "demand_scale", "requested_veh_h", "served_veh_h", "insertion_backlog", "teleports",
            "collisions", "n_vehicles", "n_rows", "n_merges", "n_encounter_frames",
            "table_sha256", "scenario_sha256", "out_dir"]
    rows = [{c: r.get(c) for c in cols} for r in report.results.values()]
    table = pd.DataFrame(rows, columns=cols)
    prov = provenance()
    for key in ("merge_irl", "sumo", "git_commit"):
        table[key] = prov.get(key)
    write_timings(path, {"sim_wall_time_s": {r.get("run"): r.get("sim_wall_time_s") for r in report.results.values()}})
    return write_atomic(path, lambda p: table.to_csv(p, index=False))


def generate_many(
    spec: ScenarioSpec,
    seeds: Sequence[int],
    demand_scales: Sequence[float] | None,
    out_dir: str | Path,
    *,
    duration_s: float | None = None,
    csv: bool = False,
    executor: str = "process",
    retries: int = 1,
    progress: bool = True,
    encounter_rule: str = ENCOUNTER_RULES[0],
) -> SweepReport:
    """Generate ``spec`` for every seed x demand scale under ``out_dir``; resumable.

    Args:
        spec: the base scenario.
        seeds: SUMO seeds, one run each (per demand scale).
        demand_scales: factors on every demand flow, or None: the spec's demand, and run
            folders without the ``-demand<X>`` suffix.
        out_dir: the sweep's folder (runs, store and ``sweep.csv`` go there).
        duration_s: simulated seconds per run (default: the spec's).
        csv: also write each run's ``trajectories.csv``.
        executor: ``"process[:N]"`` (default, every core), ``"serial"``, ``"dask-local[:N]"``
            or ``"dask://HOST:PORT"`` (see :mod:`analysis.sweep.executors`).
        retries: extra attempts of a failed run.
        progress: one progress bar (runs done / total) on stderr.
        encounter_rule: how each run becomes demonstrations (:mod:`sim.merges.demonstrators`).

    Returns:
        The :class:`SweepReport`: ``results[run_name]`` is :func:`generate_one`'s summary;
        ``failures`` lists runs that failed on every attempt (the others are complete).

    Raises:
        SpecError: an override (seed, duration, demand scale) is invalid; nothing is run.
    """
    out = Path(out_dir)
    check_rule(encounter_rule)
    tasks = generate_tasks(spec, seeds, demand_scales, out, duration_s=duration_s, csv=csv,
                           encounter_rule=encounter_rule)
    if _runs_to_do(tasks, out):  # an unusable Dask scheduler: one error, nothing created in ``out``
        check_executor(executor)
    with locked(out):
        out.mkdir(parents=True, exist_ok=True)
        remove_temporaries(out)
        store = ResultStore(out / STORE_DIR)
        store.remove_temporaries()
        _forget_missing_outputs(tasks, store)
        try:
            report = run_sweep(tasks, seed=SWEEP_SEED, executor=executor, store=store, retries=retries,
                               progress=progress, desc=f"generate {spec.name}")
        except (KeyboardInterrupt, ConnectionError):  # what finished is in the store: summarise it, then stop
            write_summary(_stored(tasks, store), out / SUMMARY)
            raise
        finally:  # staging folders and locks of runs whose worker died (killed, out of memory)
            remove_temporaries(out)
            remove_stale_locks(out)
        write_summary(_here(report, tasks), out / SUMMARY)
    return report


def _here(report: SweepReport, tasks: Sequence[Task]) -> SweepReport:
    """``report`` with each result's ``out_dir`` where the run is now (a stored result keeps
    the folder it was written to; the sweep folder may have moved since)."""
    where = {t.key: t.config.run_dir for t in tasks}
    return replace(report, results={k: {**r, "out_dir": where.get(k, r.get("out_dir"))}
                                    for k, r in report.results.items()})


def _stored(tasks: Sequence[Task], store: ResultStore) -> SweepReport:
    """A report of the finished runs found in ``store`` (after an interrupted sweep)."""
    results = {}
    for t in tasks:
        record = store.get(task_digest(t.func_name, t.config, derive_seed(SWEEP_SEED, t.key)))
        if record is not None:
            results[t.key] = {**record["result"], "out_dir": t.config.run_dir}
    return SweepReport(results=results, seeds={}, failures=(), n_cached=len(results), n_run=0, wall_time_s=0.0)


def parse_seeds(text: str) -> tuple[int, ...]:
    """``"1,2,3"``, ``"1-10"`` or a mix (``"1-3,7"``) -> distinct seeds in the order given.

    Raises:
        ValueError: a part is not ``N`` or ``N-M`` (``N <= M``, integers >= 0).
    """
    out: list[int] = []
    for part in text.split(","):
        part = part.strip()
        lo, sep, hi = part.partition("-")
        try:
            if sep and lo:
                a, b = int(lo), int(hi)
                if b < a:
                    raise ValueError
                values: range | list[int] = range(a, b + 1)
            else:
                values = [int(part)]
        except ValueError:
            raise ValueError(f"seeds {text!r}: {part!r} is not N or N-M (N <= M, integers >= 0)") from None
        for v in values:
            if v < 0:
                raise ValueError(f"seeds {text!r}: {v} is negative")
            if v not in out:
                out.append(v)
    return tuple(out)


def parse_scales(text: str) -> tuple[float, ...]:
    """``"0.5,1,2"`` -> distinct positive demand factors in the order given.

    Raises:
        ValueError: a part is not a positive finite number.
    """
    out: list[float] = []
    for part in text.split(","):
        try:
            v = float(part)
        except ValueError:
            raise ValueError(f"demand scales {text!r}: {part.strip()!r} is not a number") from None
        if not (v > 0 and v != float("inf")):
            raise ValueError(f"demand scales {text!r}: {part.strip()!r} must be a positive finite number")
        if v not in out:
            out.append(v)
    return tuple(out)
