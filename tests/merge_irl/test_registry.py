"""The one registry type: lazy entries, order, one error class, and every registry built on it."""

import subprocess
import sys

import pytest

from merge_irl.registry import Registry, RegistryError


def test_lazy_entries_import_on_first_read_and_keep_registration_order():
    r: Registry = Registry("thing")
    r.register("b", "os.path:join")
    r.register("a", 42)
    assert list(r) == ["b", "a"] and r.names() == ("b", "a") and len(r) == 2
    assert r._entries["b"] == "os.path:join"  # not imported until read
    import os.path
    assert r["b"] is os.path.join and r.get("a") == 42 and r.get("zz") is None and "zz" not in r


def test_one_error_class_with_a_one_line_message_listing_the_names():
    r: Registry = Registry("thing")
    r.register("x", 1)
    with pytest.raises(RegistryError, match=r"^unknown thing 'y'; expected one of: x$"):
        r["y"]
    with pytest.raises(RegistryError, match="thing 'x' is registered already"):
        r.register("x", 2)
    r.register("x", 2, replace=True)
    assert r["x"] == 2
    r.register("bad", "no.such.module:thing")
    with pytest.raises(RegistryError, match="does not name an importable object"):
        r["bad"]
    with pytest.raises(RegistryError, match="needs a name"):
        r.register(" ", 3)
    assert r.pop("x") == 2 and "x" not in r
    r.unregister("absent")  # no error


def test_a_lazy_entry_is_checked_when_imported():
    def check(name, entry):
        if not callable(entry):
            raise RegistryError(f"{name}: not callable")
    r: Registry = Registry("fn", check=check)
    r.register("sep", "os:sep")
    with pytest.raises(RegistryError, match="sep: not callable"):
        r["sep"]
    with pytest.raises(TypeError, match="must subclass RegistryError"):
        Registry("x", error=ValueError)  # type: ignore[arg-type]


def test_every_registry_is_a_registry_and_keeps_its_old_error_class():
    from irl.baselines import BASELINE_FITTERS
    from irl.errors import ConfigError
    from irl.methods.registry import REGISTRY
    from irl.problems import DOMAINS
    from sim.drivers.baselines import BASELINES
    from sim.drivers.formats import FORMATS
    from sim.drivers.policy import PolicyError
    from sim.env.task_reward import TASK_REWARDS
    from sim.errors import TrajectoryFormatError
    from sim.runtime.sites import SITES

    olds = [(REGISTRY, ConfigError), (DOMAINS, ConfigError), (BASELINE_FITTERS, ConfigError),
            (FORMATS, ValueError), (BASELINES, PolicyError), (SITES, TrajectoryFormatError), (TASK_REWARDS, KeyError)]
    for reg, old in olds:
        assert isinstance(reg, Registry)
        with pytest.raises(RegistryError) as e:
            reg["no-such-name"]
        assert isinstance(e.value, old) and "\n" not in str(e.value)


def test_importing_sim_drivers_imports_no_driver_module_and_no_scipy():
    code = ("import sys, sim.drivers; "
            "bad = sorted(m for m in sys.modules if m.startswith('sim.drivers.') or m.split('.')[0] == 'scipy'); "
            "print(bad)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_the_built_in_driver_formats_import_when_read():
    code = ("import sys; from sim.drivers.formats import FORMATS; "
            "a = 'sim.drivers.planning' in sys.modules; f = FORMATS['merge-irl-planner']; "
            "print(a, 'sim.drivers.planning' in sys.modules, f.family)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "True", "merge-irl-planner"]
