"""``generate``: simulate a scenario and write trajectories, encounters and the spec used.

Files written into the output folder (each atomically; see ``sim.runtime.outputs``):

* ``trajectories.parquet``  the NGSIM-schema trajectory table;
* ``encounters.parquet``    per-frame merge encounters (``irl.domains.merge.encounters.ENCOUNTER_SCHEMA``);
* ``merges.parquet``        one row per merging vehicle (``sim.merges.encounters.MERGE_COLUMNS``);
* ``scenario.toml``         the spec simulated, with the seed and duration actually used;
* ``run.toml``              how the encounters were cut (``encounter_rule``) and what SUMO reported
  (:class:`sim.runtime.run_result.RunEvents`): requested and served flow, insertion backlog, teleports,
  collisions, emergency stops, and the merges left out;
* ``trajectories.csv``      on request, in NGSIM's text format (``sim.ngsim.io``).

The files are published as a set (:mod:`merge_irl.run_folder`): written into a hidden staging folder
beside the output folder, then renamed into place in one step, so a run killed at any point
publishes nothing under the final name. The output folder is locked for the run (a second run
into it fails at once), must hold nothing but a previous run's files (removed before simulating,
so an aborted rerun never leaves them looking like this run's), and is checked writable before
the simulation starts. Leftovers of killed runs (staging folders, temporary files) are removed.
"""

from __future__ import annotations

import math
import shutil
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from merge_irl.atomic import write_text_atomic
from merge_irl.run_folder import (
    check_replaceable,
    locked,
    publish,
    remove_temporaries,
    staging_folder,
)
from scenarios.spec.model import ScenarioSpec
from scenarios.spec.parse import with_overrides
from scenarios.toml_write import dumps
from sim.merges.demonstrators import simulate_demonstrations
from sim.merges.encounters import Encounters, EncounterWindow
from sim.merges.rules import ENCOUNTER_RULES, check_rule
from sim.runtime.hooks import StepHook
from sim.runtime.outputs import write_parquet
from sim.runtime.run_result import SimulationResult

TRAJECTORIES = "trajectories.parquet"
ENCOUNTERS = "encounters.parquet"
MERGES = "merges.parquet"
SCENARIO = "scenario.toml"
RUN_REPORT = "run.toml"
CSV = "trajectories.csv"
OUTPUT_FILES = (TRAJECTORIES, ENCOUNTERS, MERGES, SCENARIO, RUN_REPORT, CSV)


@dataclass(frozen=True)
class GenerateResult:
    """What :func:`generate` simulated and wrote."""

    out_dir: Path
    files: tuple[Path, ...]
    simulation: SimulationResult
    encounters: Encounters


def default_out_dir(spec: ScenarioSpec, seed: int | None = None) -> Path:
    """``./runs/<scenario>-<seed>``."""
    return Path("runs") / f"{spec.name}-{spec.simulation.seed if seed is None else seed}"


def generate(
    spec: ScenarioSpec,
    out_dir: str | Path | None = None,
    *,
    seed: int | None = None,
    duration_s: float | None = None,
    csv: bool = False,
    progress: bool = False,
    window: EncounterWindow = EncounterWindow(),
    hooks: Sequence[StepHook] = (),
    encounter_rule: str = ENCOUNTER_RULES[0],
) -> GenerateResult:
    """Simulate ``spec`` (optionally with another seed / duration) and write the output files.

    ``encounter_rule``: how the run becomes demonstrations (:mod:`sim.merges.demonstrators`):
    ``"in-lane"`` (default) SUMO's drivers observed by the closed-loop controller with A's lane
    changes off, encounters cut by the controller's rule; ``"take-over"`` the same cut without
    holding A's lane; ``"merge-frame"`` the lag car at B's merge frame over ``window``.

    Raises:
        ValueError: an unknown ``encounter_rule``, or ``window`` given with a rule other than
            ``"merge-frame"``.
        SimulationError: SUMO fails to start or to step.
        OutputLockedError: another run is writing into the output folder.
        FileExistsError: the output folder holds files that are not a previous run's outputs.
        OSError: the output folder cannot be written (checked before simulating).
    """
    check_rule(encounter_rule, custom_window=window != EncounterWindow())
    if seed is not None or duration_s is not None:
        spec = with_overrides(spec, seed=seed, duration_s=duration_s)
    final = Path(out_dir) if out_dir is not None else default_out_dir(spec)
    with locked(final):
        check_replaceable(final, OUTPUT_FILES)
        remove_temporaries(final.resolve().parent, final.resolve().name)  # stale staging folders
        remove_temporaries(final)
        for name in OUTPUT_FILES:
            (final / name).unlink(missing_ok=True)
        stage = staging_folder(final)
        try:
            res = _generate_into(stage, spec, csv=csv, progress=progress, window=window, hooks=hooks,
                                 encounter_rule=encounter_rule)
            publish(stage, final)
        finally:
            if stage.exists():
                shutil.rmtree(stage, ignore_errors=True)
    files = tuple(final / p.name for p in res.files)
    return GenerateResult(out_dir=final, files=files, simulation=res.simulation, encounters=res.encounters)


def _generate_into(out: Path, spec: ScenarioSpec, *, csv: bool, progress: bool, window: EncounterWindow,
                   hooks: Sequence[StepHook], encounter_rule: str) -> GenerateResult:
    """Simulate and write every output file into the (staging) folder ``out``."""
    result, enc = simulate_demonstrations(spec, encounter_rule, hooks=hooks, progress=progress, window=window)
    files = [
        write_parquet(result.table, out / TRAJECTORIES),
        write_parquet(enc.frames, out / ENCOUNTERS),
        write_parquet(enc.merges, out / MERGES),
        write_text_atomic(out / SCENARIO, spec.to_toml()),
        write_text_atomic(out / RUN_REPORT, run_report_toml(result, enc, encounter_rule)),
    ]
    if csv:
        from sim.ngsim.io import write_ngsim_csv

        files.append(Path(write_ngsim_csv(result.table, out / CSV)))
    return GenerateResult(out_dir=out, files=tuple(files), simulation=result, encounters=enc)


def run_report_toml(result: SimulationResult, enc: Encounters, encounter_rule: str | None = None) -> str:
    """``run.toml``: SUMO's events and the served demand of ``result``, the merges left out, and
    how the encounters were cut (``encounter_rule``, :mod:`sim.merges.demonstrators`; the auxiliary
    lane's start ``aux_lane_start_ft`` the take-over zone is measured from)."""
    ev: dict = {}
    if encounter_rule is not None:
        ev["encounter_rule"] = encounter_rule
    if math.isfinite(result.aux_lane_start_ft):
        ev["aux_lane_start_ft"] = float(result.aux_lane_start_ft)
    ev.update(result.events.as_dict())
    ev["merges_left_out"] = [{"B_id": int(b), "merge_frame": int(f), "reason": str(r)}
                             for b, f, r in enc.excluded.itertuples(index=False)]
    ev["warnings"] = result.events.warnings()
    return dumps({"run": ev})
