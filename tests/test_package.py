"""The package installs, its command line starts, and irl/ never imports SUMO."""

import subprocess
import sys


def test_cli_help_lists_commands():
    out = subprocess.run(
        [sys.executable, "-m", "analysis", "--help"], capture_output=True, text=True, check=True
    )
    assert "merge-irl" in out.stdout


def test_irl_does_not_import_sumo():
    code = (
        "import sys, irl, importlib, pkgutil\n"
        "for m in pkgutil.walk_packages(irl.__path__, 'irl.'):\n"
        "    importlib.import_module(m.name)\n"
        "bad = [m for m in sys.modules if m.split('.')[0] in ('libsumo', 'traci', 'sumolib', 'sumo')]\n"
        "assert not bad, bad\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_layering_of_the_domain_and_units():
    # at run time, as the import graph test says from the source: irl (every module, the merge
    # domain included) loads nothing of sim/analysis/scenarios, and scenarios nothing of irl, sim
    # or analysis (their floor is merge_irl)
    code = (
        "import sys, irl, importlib, pkgutil\n"
        "for m in pkgutil.walk_packages(irl.__path__, 'irl.'):\n"
        "    importlib.import_module(m.name)\n"
        "bad = [m for m in sys.modules if m.split('.')[0] in ('sim', 'analysis', 'scenarios')]\n"
        "assert not bad, bad\n"
        "for m in [m for m in sys.modules if m.split('.')[0] == 'irl']: del sys.modules[m]\n"
        "import scenarios, scenarios.loader, scenarios.network\n"
        "assert not [m for m in sys.modules if m.split('.')[0] in ('sim', 'analysis', 'irl')]\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
