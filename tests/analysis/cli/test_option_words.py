"""The commands' options agree on their words: one spelling per meaning across every
``merge-irl`` command (progress, output, seed, workers, executor), and ``learn-driver --quiet``,
the one older spelling of ``--no-progress``, still works for one release with a one-line note."""

from __future__ import annotations

import argparse

import pytest

from analysis.cli.commands._arg_types import DeprecatedFlag
from analysis.cli.main import build_parser, main


def _commands(parser: argparse.ArgumentParser, prefix: str = "") -> dict[str, argparse.ArgumentParser]:
    out = {}
    for a in parser._actions:
        if isinstance(a, argparse._SubParsersAction):
            for name, sub in a.choices.items():
                full = f"{prefix} {name}".strip()
                inner = _commands(sub, full)
                out.update(inner or {full: sub})
    return out


COMMANDS = _commands(build_parser(load_all=True))


def _visible(dest: str) -> dict[str, tuple[str, ...]]:
    """Per command, the option strings of the visible options storing to ``dest``."""
    return {name: tuple(o for a in p._actions if a.dest == dest and a.help != argparse.SUPPRESS
                        for o in a.option_strings)
            for name, p in COMMANDS.items() if any(a.dest == dest for a in p._actions)}


def test_every_command_is_walked():
    assert {"generate", "learn", "learn-driver", "evaluate", "demo", "dagger", "reproduce", "calibrate fit"} <= set(COMMANDS)


@pytest.mark.parametrize("dest, spelling", [("no_progress", ("--no-progress",)), ("out", ("--out",)),
                                            ("seed", ("--seed",)), ("workers", ("--workers",)),
                                            ("executor", ("--executor",))])
def test_one_spelling_per_meaning(dest, spelling):
    found = _visible(dest)
    assert len(found) >= 2 and set(found.values()) == {spelling}, found


def test_no_command_spells_progress_another_way():
    others = {"--quiet", "--silent", "--progress", "--no-progress-bar", "-q"}
    shown = {name: sorted(o for a in p._actions if a.help != argparse.SUPPRESS for o in a.option_strings) for name, p in
             COMMANDS.items()}
    assert {name: sorted(set(opts) & others) for name, opts in shown.items() if set(opts) & others} == {}
    assert "learn-driver" in _visible("no_progress")


def test_learn_driver_quiet_still_silences_with_one_line_naming_no_progress(capsys):
    base = ["learn-driver", "--demos", "x.parquet", "--out", "d.json"]
    args = build_parser().parse_args([*base, "--quiet"])
    assert args.no_progress is True
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "merge-irl learn-driver: warning: --quiet is deprecated" in err[0]
    assert err[0].endswith("use --no-progress")
    args = build_parser().parse_args([*base, "--no-progress"])
    assert args.no_progress is True and capsys.readouterr().err == ""
    args = build_parser().parse_args(base)
    assert args.no_progress is False and capsys.readouterr().err == ""


def test_the_deprecated_spelling_is_not_in_help(capsys):
    with pytest.raises(SystemExit):
        main(["learn-driver", "--help"])
    text = capsys.readouterr().out
    assert "--no-progress" in text and "--quiet" not in text
    quiet = [a for a in COMMANDS["learn-driver"]._actions if "--quiet" in a.option_strings]
    assert len(quiet) == 1 and isinstance(quiet[0], DeprecatedFlag) and quiet[0].dest == "no_progress"
