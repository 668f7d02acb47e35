"""Site profiles: what each ``Lane_ID`` code means at a recording site.

Lane coding is a property of the site, declared, never guessed:

* ``i-80`` (NGSIM I-80, Emeryville; also every simulated run): main lanes 1-6 from the left
  (1 is the HOV lane), 7 the on-ramp and its auxiliary lane; merges go from 7 into 6.
* ``us-101`` (NGSIM US-101, Hollywood Freeway): main lanes 1-5, 6 the auxiliary lane, 7 the
  on-ramp, 8 the off-ramp; merges go from the on-ramp (through the auxiliary lane) into 5.
* a custom profile from a TOML file (:func:`load_site`)::

      name = "my-site"
      main_lanes = [1, 2, 3]      # left to right
      merge_lane = 3              # the main lane ramp vehicles merge into (default: the last)
      ramp_lanes = [4]            # where a merging vehicle starts
      auxiliary_lanes = []        # acceleration / weaving lanes (a merge may pass through)
      other_lanes = [9]           # known lanes not used for merges (off-ramps, shoulders)

A merging vehicle B has a row in a ramp lane followed later by a row in the merge lane; the
lag and lead vehicles are the merge lane's. A ``Lane_ID`` code that the profile does not list
is an error (:func:`check_lanes`), never silently used.
"""

from __future__ import annotations

import os
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from merge_irl.registry import Registry, RegistryError
from sim.errors import TrajectoryFormatError
from sim.runtime.schema import RAMP_LANE, RIGHTMOST_MAIN_LANE


@dataclass(frozen=True)
class SiteProfile:
    """Lane coding of one site (lane codes as in the file's ``Lane_ID``).

    Raises:
        ValueError: a lane listed twice, an empty ``main_lanes`` / ``ramp_lanes``, or a
            ``merge_lane`` that is not a main lane.
    """

    name: str
    main_lanes: tuple[int, ...]
    merge_lane: int
    ramp_lanes: tuple[int, ...]
    auxiliary_lanes: tuple[int, ...] = ()
    other_lanes: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        if not self.main_lanes or not self.ramp_lanes:
            raise ValueError(f"site {self.name!r}: main_lanes and ramp_lanes must not be empty")
        if self.merge_lane not in self.main_lanes:
            raise ValueError(f"site {self.name!r}: merge_lane {self.merge_lane} is not one of "
                             f"main_lanes {list(self.main_lanes)}")
        all_ = self.main_lanes + self.ramp_lanes + self.auxiliary_lanes + self.other_lanes
        dup = sorted({x for x in all_ if all_.count(x) > 1})
        if dup:
            raise ValueError(f"site {self.name!r}: lane(s) {dup} listed under two roles")

    @property
    def known_lanes(self) -> tuple[int, ...]:
        return tuple(sorted(self.main_lanes + self.ramp_lanes + self.auxiliary_lanes + self.other_lanes))

    def describe(self) -> str:
        parts = [f"main {list(self.main_lanes)} (merges into {self.merge_lane})", f"ramp {list(self.ramp_lanes)}"]
        if self.auxiliary_lanes:
            parts.append(f"auxiliary {list(self.auxiliary_lanes)}")
        if self.other_lanes:
            parts.append(f"other {list(self.other_lanes)}")
        return f"{self.name}: " + ", ".join(parts)


I80 = SiteProfile("i-80", tuple(range(1, RIGHTMOST_MAIN_LANE + 1)), RIGHTMOST_MAIN_LANE, (RAMP_LANE,))
US101 = SiteProfile("us-101", (1, 2, 3, 4, 5), 5, (7,), auxiliary_lanes=(6,), other_lanes=(8,))

class SiteRegistryError(RegistryError, TrajectoryFormatError):
    """An unknown site profile, or one registered twice (a :class:`TrajectoryFormatError`)."""


#: Profiles by name (lower case): the built-in ones and any :func:`register_site` added.
SITES: Registry[SiteProfile] = Registry("site", error=SiteRegistryError)


def register_site(site: SiteProfile) -> SiteProfile:
    """Add ``site`` to :data:`SITES` under its lower-cased name (for :func:`load_site`); returns it.

    Raises:
        SiteRegistryError (a TrajectoryFormatError): a site of that name is registered already.
    """
    SITES.register(site.name.strip().lower(), site)
    return site


register_site(I80)
register_site(US101)


def site_of(spec: object) -> SiteProfile:
    """The lane coding of a simulated scenario: the profile its ``site`` names
    (:attr:`scenarios.spec.model.ScenarioSpec.site`: a name or TOML path for :func:`load_site`,
    or a :class:`SiteProfile`), I-80's without one (every preset: main lanes ``7 - n .. 6``, ramp
    and auxiliary lane 7).

    A simulated road's lanes take the site's last ``main_lanes`` main lanes from the left and its
    first ramp lane; the controller takes over on the site's ramp lane and controls the lag car in
    its ``merge_lane``.

    Raises:
        TrajectoryFormatError: the named site is unknown (see :func:`load_site`).
    """
    site = getattr(spec, "site", None)
    if site is None:
        return I80
    return site if isinstance(site, SiteProfile) else load_site(site)


def _lanes(path: Path, d: dict, key: str, required: bool) -> tuple[int, ...]:
    if key not in d:
        if required:
            raise TrajectoryFormatError(f"{path}: key {key}: missing; expected a list of lane codes")
        return ()
    v = d[key]
    if not isinstance(v, list) or not all(isinstance(x, int) and not isinstance(x, bool) for x in v):
        raise TrajectoryFormatError(f"{path}: key {key}: {v!r}; expected a list of integer lane codes")
    return tuple(v)


def load_site(spec: str | os.PathLike) -> SiteProfile:
    """A built-in profile by name (``i-80``, ``us-101``, case-insensitive) or one from a TOML file.

    Raises:
        TrajectoryFormatError: unknown name, unreadable file, or a bad key (named).
        FileNotFoundError: ``spec`` looks like a file path and does not exist.
    """
    key = str(spec).strip().lower()
    if key in SITES:
        return SITES[key]
    path = Path(spec)
    if path.suffix.lower() != ".toml":
        raise TrajectoryFormatError(
            f"site {str(spec)!r}: unknown; expected one of {sorted(SITES)} or a .toml lane mapping")
    if not path.is_file():
        raise FileNotFoundError(f"site file not found: {path}")
    try:
        d = tomllib.loads(path.read_text(encoding="utf-8-sig"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise TrajectoryFormatError(f"{path}: not valid TOML: {e}") from e
    unknown = sorted(set(d) - {"name", "main_lanes", "merge_lane", "ramp_lanes", "auxiliary_lanes", "other_lanes"})
    if unknown:
        raise TrajectoryFormatError(f"{path}: unknown key(s) {unknown}")
    main = _lanes(path, d, "main_lanes", True)
    merge = d.get("merge_lane", main[-1] if main else None)
    if not isinstance(merge, int) or isinstance(merge, bool):
        raise TrajectoryFormatError(f"{path}: key merge_lane: {merge!r}; expected an integer lane code")
    try:
        return SiteProfile(str(d.get("name", path.stem)), main, merge, _lanes(path, d, "ramp_lanes", True),
                           _lanes(path, d, "auxiliary_lanes", False), _lanes(path, d, "other_lanes", False))
    except ValueError as e:
        raise TrajectoryFormatError(f"{path}: {e}") from e


def check_lanes(lane_id: np.ndarray, site: SiteProfile, source: str = "trajectory table") -> None:
    """Raise if ``lane_id`` (int[N]) holds codes the site does not list.

    Raises:
        TrajectoryFormatError: naming the column, the unknown codes with their row counts and
            the site's coding.
    """
    codes, counts = np.unique(np.asarray(lane_id, dtype=np.int64), return_counts=True)
    bad = ~np.isin(codes, np.asarray(site.known_lanes, dtype=np.int64))
    if bad.any():
        found = ", ".join(f"{int(c)} ({int(n)} rows)" for c, n in zip(codes[bad], counts[bad]))
        raise TrajectoryFormatError(
            f"{source}: column Lane_ID: code(s) {found} are not lanes of site {site.describe()}; "
            f"declare the site's lane coding (built in: {', '.join(sorted(SITES))}; or a TOML "
            "mapping, see sim.runtime.sites)"
        )
