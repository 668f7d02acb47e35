"""Find and load scenarios: a preset shipped in ``scenarios/presets/`` or a user's TOML file."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from scenarios.errors import SpecError
from scenarios.spec.model import ScenarioSpec
from scenarios.spec.parse import spec_from_file, spec_from_toml

DEFAULT_SCENARIO = "synthetic"


def preset_names() -> tuple[str, ...]:
    """Names of the presets shipped with the package, sorted."""
    folder = resources.files("scenarios") / "presets"
    return tuple(sorted(p.name[: -len(".toml")] for p in folder.iterdir() if p.name.endswith(".toml")))


def load_preset(name: str, *, allow_implausible: bool = False) -> ScenarioSpec:
    """The preset ``name``; ``SpecError`` listing the presets if there is none of that name
    (``allow_implausible``: as :func:`scenarios.spec.parse.spec_from_dict`'s).

    Raises:
        SpecError: there is no preset of that name (the message lists the presets).
    """
    if name not in preset_names():
        raise SpecError(f"scenario: unknown preset {name!r} (presets: {', '.join(preset_names())}; or give a .toml file)")
    text = (resources.files("scenarios") / "presets" / f"{name}.toml").read_text(encoding="utf-8")
    return spec_from_toml(text, source=f"preset {name}.toml", allow_implausible=allow_implausible)


def load_scenario(name_or_path: str | Path, *, allow_implausible: bool = False) -> ScenarioSpec:
    """A preset name (``synthetic``, ``i80``) or the path of a scenario ``.toml`` file;
    ``allow_implausible``: accept values outside the plausibility bounds
    (:mod:`scenarios.spec.bounds`; ``--allow-implausible``), as the file's own
    ``allow_implausible = true`` does.

    Raises:
        SpecError: unknown preset, missing file, or an invalid field (the message names the
            file and the field).
    """
    s = str(name_or_path)
    p = Path(s)
    if isinstance(name_or_path, Path) or s.endswith(".toml") or p.exists() or "/" in s:
        if not p.is_file():
            raise SpecError(f"{s}: scenario file not found")
        return spec_from_file(p, allow_implausible=allow_implausible)
    return load_preset(s, allow_implausible=allow_implausible)
