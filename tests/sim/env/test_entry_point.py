"""The environment registered through Gymnasium's entry-point group (``gymnasium.envs``), without
``import sim.env``: pyproject declares it, the function it names registers the id as Gymnasium
0.29's ``load_plugin_envs`` calls it (inside the entry point's namespace) and imports none of the
environment, and a fresh interpreter makes the environment with Gymnasium alone when a
distribution declares the entry point (a ``.dist-info`` on its path; the installed package's own
metadata too, once installed again). Gymnasium 1.x loads no plugins: there the id names the module,
``"sim.env:MergeIRL/OnRampMerge-v0"``. ``import sim.env`` keeps registering."""

from __future__ import annotations

import importlib.metadata
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

gym = pytest.importorskip("gymnasium")  # the [gym] extra; CI installs it with [test]

from merge_irl.gym_plugin import ENV_ID, register_envs  # noqa: E402
from merge_irl.registry import resolve_ref  # noqa: E402

ROOT = Path(__file__).resolve().parents[3]
GROUP = "gymnasium.envs"


def _declared() -> dict[str, str]:
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    return meta["project"]["entry-points"][GROUP]


def _python(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=ROOT)


def test_pyproject_names_the_registering_function_under_the_ids_namespace():
    declared = _declared()
    assert list(declared) == [ENV_ID.split("/")[0]]  # the entry point's name is the id's namespace
    assert resolve_ref(declared["MergeIRL"]) is register_envs


def test_the_function_registers_the_id_as_load_plugin_envs_calls_it_and_imports_no_environment():
    r = _python(
        "import sys, tomllib\n"
        "import gymnasium as gym\n"
        "from gymnasium.envs.registration import namespace\n"
        "from merge_irl.registry import resolve_ref\n"
        "ep = tomllib.load(open('pyproject.toml', 'rb'))['project']['entry-points']['gymnasium.envs']\n"
        "for name, value in ep.items():\n"
        "    with namespace(name):\n"
        "        resolve_ref(value)()\n"
        "        resolve_ref(value)()  # twice: still one registration\n"
        "assert 'sim.env' not in sys.modules, 'registering imported the environment'\n"
        f"env = gym.make({ENV_ID!r}, run_s=240.0)\n"
        "print(type(env.unwrapped).__module__, env.spec.id, env.spec.max_episode_steps)\n"
        "env.close()\n")
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["sim.env.merge_env", ENV_ID, "200"]


def test_import_sim_env_still_registers_the_id():
    r = _python(f"import gymnasium as gym, sim.env\nprint({ENV_ID!r} in gym.registry)")
    assert r.returncode == 0 and r.stdout.strip() == "True", r.stderr


#: A fresh interpreter makes the environment with Gymnasium alone: 0.29 registers it on ``import
#: gymnasium`` (the entry point); 1.x loads no plugins, and the id names the module to import.
_MAKE_WITH_GYMNASIUM_ALONE = (
    "import sys\n"
    "import gymnasium as gym\n"
    f"on_import = {ENV_ID!r} in gym.registry\n"
    "assert 'sim.env' not in sys.modules, 'the entry point imported the environment'\n"
    f"env = gym.make({ENV_ID!r} if on_import else 'sim.env:{ENV_ID}', run_s=240.0)\n"
    "print(gym.__version__, on_import, type(env.unwrapped).__name__)\n"
    "env.close()\n")


def _installed() -> str | None:
    """The installed package's ``gymnasium.envs`` entry point value, None when it has none."""
    for ep in importlib.metadata.entry_points(group=GROUP):
        if ep.name == "MergeIRL":
            return ep.value
    return None


def test_the_installed_entry_point_makes_the_env_with_gymnasium_alone():
    installed = _installed()
    if installed != _declared()["MergeIRL"]:
        pytest.skip(f"the installed package's metadata has {GROUP} entry point {installed!r}, not this checkout's "
                    "(an install that predates it: pip install -e . again)")
    r = _python(_MAKE_WITH_GYMNASIUM_ALONE)
    assert r.returncode == 0, r.stderr
    version, on_import, cls = r.stdout.split()
    assert cls == "MergeEnv" and on_import == str(version.startswith("0."))


def test_a_distribution_with_the_declared_entry_point_makes_the_env_with_gymnasium_alone(tmp_path):
    """The same path before the package is installed again: a ``.dist-info`` folder with this
    checkout's entry point, as pip writes it, on the path of a fresh interpreter."""
    dist = tmp_path / "merge_irl_entry_probe-0.0.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: merge-irl-entry-probe\nVersion: 0.0\n")
    lines = "".join(f"{name} = {value}\n" for name, value in _declared().items())
    (dist / "entry_points.txt").write_text(f"[{GROUP}]\n{lines}")
    r = _python(f"import sys\nsys.path.insert(0, {str(tmp_path)!r})\n" + _MAKE_WITH_GYMNASIUM_ALONE)
    assert r.returncode == 0, r.stderr
    version, on_import, cls = r.stdout.split()
    assert cls == "MergeEnv"
    assert on_import == str(version.startswith("0.")), "Gymnasium 0.29 loads the group on import, 1.x has no plugins"
