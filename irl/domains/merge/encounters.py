"""The encounter table of the freeway-merge domain: its columns, dtypes
and units (:data:`~irl.domains.merge.encounters.ENCOUNTER_SCHEMA`), and the check a table passes before it is binned or
learned from (:func:`~irl.domains.merge.encounters.validate_encounters`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from irl.errors import DemonstrationError


@dataclass(frozen=True)
class EncounterColumn:
    """One column of the encounter table: ``name``, pandas ``dtype``, ``unit`` and meaning."""

    name: str
    dtype: str
    unit: str
    doc: str


#: The per-frame encounter table, one row per frame t of an encounter
#: in which A, B and A's speed at t + 0.1 s are known. ``sim.merges.encounters`` writes it from any
#: NGSIM-schema trajectory table (simulated or real); ``irl.domains.merge.mdp`` learns from it.
ENCOUNTER_SCHEMA: tuple[EncounterColumn, ...] = (
    EncounterColumn("encounter_id", "int64", "", "one id per merge (per car B), from 1"),
    EncounterColumn("B_id", "int64", "", "Vehicle_ID of the merging car B"),
    EncounterColumn("A_id", "int64", "", "Vehicle_ID of the lag car A (lane 6, behind B at the merge frame; simulated runs: at the take-over)"),
    EncounterColumn("C_id", "int64", "", "Vehicle_ID of the lead car C (lane 6, ahead of B at the merge frame; simulated runs: A's lead other than B in this frame); 0: none"),
    EncounterColumn("Frame_ID", "int64", "0.1 s frame", "the frame t of this row"),
    EncounterColumn("Global_Time", "int64", "ms", "time of frame t"),
    EncounterColumn("merge_frame", "int64", "0.1 s frame", "B's first frame in lane 6"),
    EncounterColumn("d_AC", "float64", "ft", "Local_Y(C) - Local_Y(A); NaN when C is not there (no-lead-car rule)"),
    EncounterColumn("d_AB", "float64", "ft", "Local_Y(B) - Local_Y(A); negative while B is behind A"),
    EncounterColumn("v_AC", "float64", "ft/s", "v(A) - v(C); NaN exactly when d_AC is"),
    EncounterColumn("v_AB", "float64", "ft/s", "v(A) - v(B)"),
    EncounterColumn("B_is_truck", "bool", "", "B's v_Class is 3 (truck)"),
    EncounterColumn("acc_A", "float64", "ft/s^2",
                    "the action: (v_A(t+1) - v_A(t)) / 0.1 s, forward difference of A's speed "
                    "(not v_Acc, the backward difference)"),
    EncounterColumn("v_A", "float64", "ft/s",
                    "A's speed v_Vel(A) at frame t (the car-following features and the closed loop's W1 of "
                    "speed use it; not required for the tabular methods)"),
    EncounterColumn("len_C", "float64", "ft",
                    "C's length v_Length in frame t (d_AC minus it is the bumper gap A follows at); NaN without C, "
                    "or when unknown (no v_Length column, or not > 0); used by the car-following features only"),
    EncounterColumn("len_B", "float64", "ft",
                    "B's length v_Length (the bumper gap to B once B is ahead of A); NaN when unknown (no v_Length "
                    "column, or not > 0); used by the car-following features only"),
    EncounterColumn("merge_observed", "bool", "",
                    "B has a row in the frame before merge_frame; False: B is first seen in lane 6 after missing "
                    "frames, so the merge happened at an unobserved frame before merge_frame (recordings with gaps)"),
)
#: Column name -> pandas dtype, in table order.
ENCOUNTER_COLUMNS: dict[str, str] = {c.name: c.dtype for c in ENCOUNTER_SCHEMA}
#: Column name -> unit ("" for ids and flags).
ENCOUNTER_UNITS: dict[str, str] = {c.name: c.unit for c in ENCOUNTER_SCHEMA}
#: The columns a table must have to be learned from (others are ignored).
REQUIRED_COLUMNS = ("encounter_id", "d_AC", "d_AB", "v_AC", "v_AB", "B_is_truck", "acc_A")


def validate_encounters(table, where: str = "encounters") -> None:
    """Check an encounter table before it is binned or learned from.

    ``d_AB``, ``v_AB``, ``B_is_truck`` and ``acc_A`` must be finite numbers; ``d_AC`` and
    ``v_AC`` finite numbers or both NaN (no car C). A table never holds ``+-inf``.

    Raises:
        DemonstrationError: not a DataFrame, a column of :data:`REQUIRED_COLUMNS` missing, no
            rows, or a bad value (the message names ``where``, the row and the column).
    """
    if not isinstance(table, pd.DataFrame):
        raise DemonstrationError(f"{where}: expected a pandas DataFrame of encounters, got {type(table).__name__}")
    missing = [c for c in REQUIRED_COLUMNS if c not in table.columns]
    if missing:
        raise DemonstrationError(
            f"{where}: encounter table lacks column(s) {missing}; expected {list(REQUIRED_COLUMNS)}"
        )
    if len(table) == 0:
        raise DemonstrationError(f"{where}: encounter table has no rows")
    cols = {c: pd.to_numeric(table[c], errors="coerce").to_numpy(dtype=np.float64) for c in REQUIRED_COLUMNS[1:]}
    no_c = np.isnan(cols["d_AC"]) & np.isnan(cols["v_AC"])
    for c, col in cols.items():
        bad = ~np.isfinite(col)
        if c in ("d_AC", "v_AC"):
            bad &= ~no_c
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            got = table[c].iloc[i]
            got = got.item() if isinstance(got, np.generic) else got
            hint = " (d_AC and v_AC are NaN together when there is no car C)" if c in ("d_AC", "v_AC") else ""
            raise DemonstrationError(
                f"{where}: row {i}, column {c!r}: expected a finite number, got {got!r}{hint}"
            )


def prepare_encounters(frames: pd.DataFrame, where: str = "encounters") -> pd.DataFrame:
    """Encounter frames ready to discretize: rows with A, B and an action only (frames without
    car C stay, with d_AC and v_AC NaN: the domain's no-lead-car rule encodes them).

    Raises:
        DemonstrationError: a column of :data:`irl.domains.merge.encounters.REQUIRED_COLUMNS` is
            missing (``where`` names the table).
    """
    missing = [c for c in REQUIRED_COLUMNS if c not in frames.columns]
    if missing:
        raise DemonstrationError(f"{where}: encounter table lacks column(s) {missing}; expected {list(REQUIRED_COLUMNS)} "
                                 "(an encounters.parquet of 'merge-irl generate' or 'merge-irl encounters')")
    df = frames.copy()
    df = df[np.isfinite(df["d_AB"]) & np.isfinite(df["v_AB"]) & np.isfinite(df["acc_A"])]
    return df.reset_index(drop=True)
