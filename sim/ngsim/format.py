"""NGSIM's vehicle-trajectory text format: column names, header, and number formatting.

The public NGSIM files come in two layouts:

* ``trajectories-0400-0415.csv`` etc.: comma-separated with a header line
  (``Vehicle_ID,Frame_ID,...,Time_Headway``); some releases spell ``v_length`` in lower case
  and add ``O_Zone, D_Zone, Int_ID, Section_ID, Direction, Movement, Location``, which are
  accepted and dropped.
* the older ``trajectories-0400-0415.txt``: whitespace-separated, no header, the 18 columns of
  :data:`sim.runtime.schema.COLUMNS` in that order.

Number formatting of the original text release (used by the writer): positions with 3
decimals, vehicle length / width with 1, speed, acceleration and headways with 2, everything
else integer.
"""

from __future__ import annotations

import unicodedata

from sim.runtime.schema import COLUMNS

#: The 18 NGSIM columns in file order (the schema's order).
NGSIM_COLUMNS: tuple[str, ...] = tuple(COLUMNS)

#: The header line NGSIM's CSV files start with (no trailing newline).
NGSIM_HEADER: str = ",".join(NGSIM_COLUMNS)

#: Decimal places NGSIM writes for each float column.
DECIMALS: dict[str, int] = {
    "Local_X": 3,
    "Local_Y": 3,
    "Global_X": 3,
    "Global_Y": 3,
    "v_Length": 1,
    "v_Width": 1,
    "v_Vel": 2,
    "v_Acc": 2,
    "Space_Headway": 2,
    "Time_Headway": 2,
}

#: Columns stored as integers.
INT_COLUMNS: tuple[str, ...] = tuple(c for c, t in COLUMNS.items() if t == "int64")

#: Extra columns some NGSIM releases carry; accepted and dropped by the reader.
KNOWN_EXTRA_COLUMNS: tuple[str, ...] = (
    "O_Zone", "D_Zone", "Int_ID", "Section_ID", "Direction", "Movement", "Location",
)


#: Other spellings found in NGSIM releases (lower case) -> schema name.
ALIASES: dict[str, str] = {"space_hdwy": "Space_Headway", "time_hdwy": "Time_Headway"}


def visible(text: str) -> str:
    """``text`` without invisible characters (byte-order marks, zero-width and other format
    characters, control characters), outer whitespace (including no-break spaces) and quotes."""
    kept = "".join(ch for ch in text if unicodedata.category(ch) not in ("Cf", "Cc"))
    return kept.strip().strip('"').strip()


def canonical_name(name: str) -> str:
    """Map a header field to the schema's spelling (case-insensitive, with :data:`ALIASES`,
    ignoring invisible characters such as a byte-order mark); unknown names are returned
    without their invisible characters."""
    shown = visible(name)
    key = shown.lower()
    if key in ALIASES:
        return ALIASES[key]
    for c in NGSIM_COLUMNS:
        if c.lower() == key:
            return c
    return shown
