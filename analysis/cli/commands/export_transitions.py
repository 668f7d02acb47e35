"""``merge-irl export-transitions``: encounters, NGSIM files and closed-loop decision logs as the
transition arrays of imitation learning (``sim.merges.transitions``)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from analysis.cli.commands._arg_types import DeprecatedAlias
from analysis.cli.options import demos_option
from irl.domains.merge.mdp import DEFAULT_DECISION_STEP_S, read_encounters
from merge_irl.tables import is_parquet_dataset, read_table, table_columns
from merge_irl.units import FRAME_S
from sim.merges.transitions import (
    TransitionsError,
    concatenate,
    from_decisions,
    from_encounters,
    from_trajectories,
    save,
)
from sim.ngsim.io import read_ngsim, read_trajectories
from sim.ngsim.smooth import SmoothingConfig

#: The output formats: a transitions .npz (sim.merges.transitions.save) or a Minari dataset.
FORMATS = ("npz", "minari")


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "export-transitions", parents=[demos_option(
            "encounter tables, NGSIM trajectory files or decision logs, kept apart as sources (episodes numbered "
            "across them)", required=True)],
        description="Read encounter tables (.parquet/.csv of 'merge-irl generate' or 'merge-irl encounters'), NGSIM "
                    "trajectory files (.csv/.txt; merges cut by the merge-frame rule) or closed-loop decision logs "
                    "(.parquet/.csv with the controller's decision columns) and write one .npz of transitions at the "
                    "decision step: obs and next_obs [N, 7] (d_AC, v_AC, d_AB, v_AB, v_A, len_C, len_B; ft, ft/s), "
                    "acts [N] (merge actions 0..4), acc_mps2 [N], dones [N], episode [N] (one per encounter or "
                    "control), read back by sim.merges.transitions.load; or, with --format minari, a Minari dataset "
                    "(minari.load_dataset; the rl extra) with the environment's spaces, rewards 0, terminations at "
                    "each episode's end and the run's provenance in its metadata (sim.env.minari_dataset).")
    p.add_argument("--format", choices=FORMATS, default="npz",
                   help="npz: one .npz file (--out FILE.npz); minari: a Minari dataset --dataset-id under the "
                        "folder --out (default MINARI_DATASETS_PATH, else ~/.minari/datasets) (default npz)")
    p.add_argument("--out", default=None, metavar="PATH",
                   help="the .npz file (--format npz, required), or the Minari datasets folder (--format minari)")
    p.add_argument("--dataset-id", default=None, metavar="ID",
                   help="--format minari: the dataset's id, (namespace/)name-v(version), e.g. merge-irl/demos-v0")
    p.add_argument("--overwrite", action="store_true",
                   help="--format minari: replace a dataset of the same id (else an existing id is refused)")
    p.add_argument("--decision-step-s", dest="decision_step_s", type=float, default=None,
                   help="seconds per decision (default 0.3; a decision log must have been decided at it)")
    # the older spelling of --decision-step-s: one release more, with a note
    p.add_argument("--decision-step", dest="decision_step_s", type=float, action=DeprecatedAlias, use="--decision-step-s")
    p.add_argument("--location", default=None, metavar="SITE",
                   help="NGSIM files with a Location column: keep this site's rows (e.g. i-80)")
    p.add_argument("--recording", type=int, default=None, metavar="N",
                   help="NGSIM files holding several recordings: keep recording N")
    p.add_argument("--smooth", action="store_true",
                   help="NGSIM files: smooth positions and recompute speeds and accelerations (Savitzky-Golay)")
    p.set_defaults(func=run)


def _kind(columns) -> str:
    cols = set(columns)
    if "encounter_id" in cols:
        return "encounters"
    if {"a_id", "speed_A", "action"} <= cols:
        return "decisions"
    if {"Vehicle_ID", "Frame_ID", "Local_Y", "Lane_ID"} <= cols:
        return "trajectories"
    return ""


def _check_output(args: argparse.Namespace) -> None:
    """Refuse, before reading anything, an output that cannot be written as asked."""
    if args.format == "npz":
        if args.dataset_id is not None or args.overwrite:
            raise TransitionsError("--dataset-id and --overwrite apply to --format minari only")
        if args.out is None:
            raise TransitionsError("--out FILE.npz is required (or give --format minari --dataset-id ID)")
        if not str(args.out).endswith(".npz"):
            raise TransitionsError(f"--out {args.out}: the file name must end in .npz")
        return
    if args.dataset_id is None:
        raise TransitionsError("--format minari needs --dataset-id ID, e.g. merge-irl/demos-v0")
    try:
        from sim.env.minari_dataset import check_dataset_id

        check_dataset_id(args.dataset_id, args.out, overwrite=args.overwrite)
    except ImportError as e:
        raise TransitionsError(f"--format minari needs Minari and Gymnasium ({e}): pip install -e '.[rl]'") from None


def _write(t, args: argparse.Namespace) -> str:
    """Write ``t`` as ``args`` ask; the path written."""
    if args.format == "npz":
        return str(save(t, args.out))
    from merge_irl.provenance import provenance
    from sim.env.minari_dataset import write_minari

    paths = list(args.demos)
    inputs = {("demos" if len(paths) == 1 else f"demos{i}"): p for i, p in enumerate(paths, start=1)}
    ds = write_minari(t, args.dataset_id, root=args.out, overwrite=args.overwrite, provenance=provenance(inputs))
    return str(ds.storage.data_path.parent)


def _source_kind(path: Path) -> str:
    """What ``path`` holds (:func:`_kind`; a ``.txt`` file is an NGSIM file), "" if none of them.

    Raises:
        TransitionsError: a missing or unreadable path, a folder without Parquet part files, or
            an unknown suffix.
    """
    if path.is_dir() and not is_parquet_dataset(path):
        hint = f" (e.g. {path / 'encounters.parquet'})" if (path / "encounters.parquet").is_file() else ""
        raise TransitionsError(f"{path}: a folder, not a file or a Parquet dataset folder; give its tables{hint}")
    if not path.exists():
        raise TransitionsError(f"{path}: no such file")
    if not path.is_dir() and path.suffix.lower() not in (".parquet", ".pq", ".csv", ".txt"):
        raise TransitionsError(f"{path}: expected a .parquet, .csv or .txt file, or a Parquet dataset folder")
    if path.suffix.lower() == ".txt" and not path.is_dir():
        return "trajectories"
    try:
        return _kind(table_columns(path, error=TransitionsError))
    except Exception as e:  # pyarrow and pandas raise many types for unreadable files
        raise TransitionsError(f"{path}: cannot read ({type(e).__name__}: {' '.join(str(e).split())})") from None


def run(args: argparse.Namespace) -> int:
    step = args.decision_step_s if args.decision_step_s is not None else DEFAULT_DECISION_STEP_S
    _check_output(args)
    ngsim_options = args.location is not None or args.recording is not None or args.smooth
    if ngsim_options and not any(Path(d).suffix.lower() in (".csv", ".txt") for d in args.demos):
        raise TransitionsError("--location, --recording and --smooth apply to NGSIM .csv/.txt files only")
    parts = []
    for path in map(Path, args.demos):
        kind = _source_kind(path)
        if not kind:
            raise TransitionsError(f"{path}: neither an encounter table (encounter_id), a decision log (a_id, speed_A, "
                                   "action) nor an NGSIM trajectory file (Vehicle_ID, Frame_ID, Local_Y, Lane_ID)")
        if kind == "encounters":
            part = from_encounters(read_encounters(path), decision_step_s=step, where=str(path))
        elif kind == "decisions":
            log = read_table(path, error=TransitionsError)
            part = from_decisions(log, where=str(path))
            if abs(part.decision_step_s - step) > FRAME_S / 2:
                raise TransitionsError(f"{path}: decided every {part.decision_step_s} s, not every {step} s "
                                       "(give --decision-step-s)")
            part = from_decisions(log, decision_step_s=step, where=str(path))
        elif path.suffix.lower() in (".csv", ".txt") and not path.is_dir():
            load = read_ngsim(path, location=args.location, recording=args.recording,
                              smooth=SmoothingConfig() if args.smooth else False)
            part = from_trajectories(load.table, decision_step_s=step, where=str(path))
        else:
            part = from_trajectories(read_trajectories(path), decision_step_s=step, where=str(path))
        print(f"{path}: {part.n} transitions, {part.n_episodes} episodes ({kind})", file=sys.stderr)
        parts.append(part)
    t = concatenate(parts)
    out = _write(t, args)
    print(f"{t.n} transitions, {t.n_episodes} episodes, obs [{t.n}, {len(t.obs_names)}] every {t.decision_step_s} s",
          file=sys.stderr)
    print(out)
    return 0
