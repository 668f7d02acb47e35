"""One meaning per spelling across the whole ``merge-irl`` parser tree: an option string has the
same destination, type, repetition rule (nargs / action) and default in every command that takes
it, except the declared entries below; deprecated spellings are listed apart. The command modules
load lazily: ``merge-irl --help`` imports none of them."""

from __future__ import annotations

import argparse
import pkgutil
import subprocess
import sys
from collections import defaultdict

import pytest

import analysis.cli.commands as commands_package
from analysis.cli.commands import COMMANDS as REGISTERED
from analysis.cli.commands import module_name
from analysis.cli.main import build_parser

#: Old spellings kept for one release (hidden from --help, one stderr line naming the new one):
#: (command, option) -> the option that replaces it. Not compared: they are aliases, not meanings.
DEPRECATED_ALIASES = {
    ("calibrate fit", "--model"): "--cf-model-name",
    ("reproduce", "--json"): "--json-out",
    ("learn-driver", "--quiet"): "--no-progress",
    ("learn", "--dt"): "--decision-step-s",
    ("dagger", "--decision-step"): "--decision-step-s",
    ("evaluate", "--decision-step"): "--decision-step-s",
    ("export-transitions", "--decision-step"): "--decision-step-s",
    ("evaluate", "--model"): "--driver",
    ("evaluate", "--cf-model"): "--driver",
}

#: (command, option) pairs allowed to differ from the option's other commands, each with why.
ALLOWED = {
    # --seed defaults to 0 everywhere, except where it overrides the seed a scenario file holds:
    # there the default is the file's own (generate's run, the preset's resample).
    ("generate", "--seed"), ("calibrate preset", "--seed"),
    # the calibration commands compare with the real I-80 pairs: their scenario is i80, not synthetic.
    ("calibrate check", "--scenario"), ("calibrate preset", "--scenario"),
    # evaluate compares several drivers (--driver repeatable: files or baseline names); score and
    # calibrate evaluate score one driver file.
    ("evaluate", "--driver"),
}


def _commands(parser: argparse.ArgumentParser, prefix: str = "") -> dict[str, argparse.ArgumentParser]:
    out = {}
    for a in parser._actions:
        if isinstance(a, argparse._SubParsersAction):
            for name, sub in a.choices.items():
                full = f"{prefix} {name}".strip()
                out.update(_commands(sub, full) or {full: sub})
    return out


COMMANDS = _commands(build_parser(load_all=True))


def _meaning(a: argparse.Action) -> tuple:
    kind = a.nargs if a.nargs is not None else type(a).__name__
    return (a.dest, getattr(a.type, "__name__", a.type), kind, type(a).__name__, repr(a.default))


def meanings() -> dict[str, dict[tuple, list[str]]]:
    """option -> its meaning -> the commands giving it that meaning (allowed and deprecated
    entries left out)."""
    found: dict[str, dict[tuple, list[str]]] = defaultdict(lambda: defaultdict(list))
    for name, p in COMMANDS.items():
        for a in p._actions:
            for o in a.option_strings:
                if o in ("-h", "--help") or (name, o) in DEPRECATED_ALIASES or (name, o) in ALLOWED:
                    continue
                found[o][_meaning(a)].append(name)
    return found


def test_the_whole_tree_is_walked():
    assert {"generate", "learn", "learn-driver", "evaluate", "demo", "dagger", "reproduce", "score",
            "calibrate fit", "calibrate evaluate", "calibrate check", "calibrate preset"} <= set(COMMANDS)
    assert {c.split()[0] for c in COMMANDS} == set(REGISTERED)
    modules = {m.name for m in pkgutil.iter_modules(commands_package.__path__) if not m.name.startswith("_")}
    assert modules == {module_name(c).rsplit(".", 1)[1] for c in REGISTERED}  # a new module is listed
    assert sum(len(p._actions) for p in COMMANDS.values()) > 150


def test_zero_options_with_two_meanings():
    two = {o: {str(m): c for m, c in ms.items()} for o, ms in meanings().items() if len(ms) > 1}
    assert not two, f"{len(two)} options with two meanings: {two}"


def test_one_spelling_per_meaning():
    """Every destination is spelled the same in every command (its visible option strings)."""
    spellings: dict[str, set[tuple[str, ...]]] = defaultdict(set)
    for name, p in COMMANDS.items():
        for a in p._actions:
            shown = tuple(o for o in a.option_strings if (name, o) not in DEPRECATED_ALIASES)
            if shown and a.help != argparse.SUPPRESS:
                spellings[a.dest].add(shown)
    two = {dest: sorted(s) for dest, s in spellings.items() if len(s) > 1 or len(next(iter(s))) > 1 and dest != "help"}
    assert not two, f"{len(two)} meanings with two spellings: {two}"


def test_deprecated_aliases_are_hidden_and_point_at_a_shown_option():
    for (name, option), new in DEPRECATED_ALIASES.items():
        (old,) = [a for a in COMMANDS[name]._actions if option in a.option_strings]
        (shown,) = [a for a in COMMANDS[name]._actions if new in a.option_strings]
        assert old.help == argparse.SUPPRESS and old.dest == shown.dest and shown.help != argparse.SUPPRESS
        assert old.option_strings == [option] and getattr(old, "use", None) == new


def test_the_shared_options_are_shared():
    """--workers, --executor, --no-progress and --seed are in several commands, with one meaning."""
    found = meanings()
    for option in ("--workers", "--executor", "--no-progress", "--seed", "--demos", "--episodes", "--l2"):
        assert len(found[option]) == 1 and len(next(iter(found[option].values()))) >= 2, (option, found[option])
    ((dest, _, _, _, default),) = found["--workers"]
    assert (dest, default) == ("workers", "None")  # every core, through analysis.sweep.resolve_executor


def test_every_allow_list_entry_is_still_needed():
    """An entry whose option no longer differs (or is gone) is taken out of the list."""
    for name, option in ALLOWED | set(DEPRECATED_ALIASES):
        actions = [a for a in COMMANDS[name]._actions if option in a.option_strings]
        assert len(actions) == 1, (name, option)
        others = {_meaning(a) for n, p in COMMANDS.items() if n != name for a in p._actions
                  if option in a.option_strings and (n, option) not in ALLOWED | set(DEPRECATED_ALIASES)}
        assert _meaning(actions[0]) not in others or not others, (name, option)


@pytest.mark.parametrize("argv, old, new, dest, value", [
    (["calibrate", "fit", "--pairs", "p", "--out", "o.toml", "--model", "krauss"], "--model", "--cf-model-name",
     "cf_model_name", "krauss"),
    (["reproduce", "--table", "1", "--json", "r.json"], "--json", "--json-out", "json_out", "r.json"),
    (["learn", "--method", "qavg", "--domain", "merge", "--demos", "d", "--out", "m.json", "--dt", "0.5"], "--dt",
     "--decision-step-s", "decision_step_s", 0.5),
])
def test_a_deprecated_alias_works_and_names_the_new_spelling(capsys, argv, old, new, dest, value):
    args = build_parser().parse_args(argv)
    assert getattr(args, dest) == value
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"warning: {old} is deprecated" in err[0] and err[0].endswith(f"use {new}")
    args = build_parser().parse_args([new if a == old else a for a in argv])
    assert getattr(args, dest) == value and capsys.readouterr().err == ""


def test_the_renamed_options_hold_their_defaults():
    fit = build_parser().parse_args(["calibrate", "fit", "--pairs", "p", "--out", "o.toml"])
    assert fit.cf_model_name == "idm" and not hasattr(fit, "model")
    rep = build_parser().parse_args(["reproduce", "--table", "1"])
    assert rep.json_out is None and rep.executor is None and rep.seed == 0


def test_help_imports_no_command_module():
    code = ("import sys, contextlib, io\nfrom analysis.cli.main import main\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n"
            "    try:\n        main(['--help'])\n    except SystemExit:\n        pass\n"
            "print(sorted(m for m in sys.modules if m.startswith('analysis.cli.commands.')))\n"
            "print('pandas' in sys.modules)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    loaded, pandas = r.stdout.strip().splitlines()
    assert loaded == "[]" and pandas == "False", r.stdout


def test_a_chosen_command_loads_only_its_module():
    args = build_parser().parse_args(["view", "x.rrd", "--print-only"])
    assert args.func.__module__ == "analysis.cli.commands.view"
