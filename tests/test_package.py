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
    # irl (the merge domain included) imports nothing of sim/analysis/scenarios; scenarios takes
    # only the leaf merge_irl.units from irl (importing it runs irl/__init__, nothing of sim/analysis)
    code = (
        "import sys, irl, importlib, pkgutil\n"
        "for m in pkgutil.walk_packages(irl.__path__, 'irl.'):\n"
        "    importlib.import_module(m.name)\n"
        "bad = [m for m in sys.modules if m.split('.')[0] in ('sim', 'analysis', 'scenarios')]\n"
        "assert not bad, bad\n"
        "for m in [m for m in sys.modules if m.split('.')[0] == 'irl']: del sys.modules[m]\n"
        "import scenarios, analysis.calibration\n"
        "assert not [m for m in sys.modules if m.split('.')[0] in ('sim', 'analysis')]\n"
        "assert not [m for m in sys.modules if m.startswith('irl.domains')], 'scenarios needs no domain'\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
