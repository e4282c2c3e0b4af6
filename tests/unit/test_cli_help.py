"""Every help text of the command line formats (argparse expands ``%`` in help strings: a bare
``95 %`` breaks ``asphalt-nscd --help``)."""

import argparse

import pytest

from asphalt_nscd.cli import build_parser, main


def _subparsers(parser):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return action.choices
    return {}


def test_top_level_help_prints(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    assert "diagnose-bench" in capsys.readouterr().out


@pytest.mark.parametrize("name", sorted(_subparsers(build_parser())))
def test_every_subcommand_help_formats(name):
    text = _subparsers(build_parser())[name].format_help()
    assert text.startswith("usage:")


def test_help_lists_every_command_by_group_with_a_description(capsys):
    """``asphalt-nscd --help`` lists each subcommand once, under its group, with its one-line
    description; every subcommand's own help opens with a description; --version and
    ``python -m asphalt_nscd`` answer."""
    import subprocess
    import sys

    from asphalt_nscd import __version__
    from asphalt_nscd.cli import GROUP_ORDER

    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    names = sorted(_subparsers(build_parser()))
    body = out.split("commands, by step of the chain:")[1]
    for name in names:
        lines = [ln for ln in body.splitlines() if ln.split()[:1] == [name]]
        assert len(lines) == 1 and len(lines[0].split()) > 2, name  # once, with a description
    assert [g for g in GROUP_ORDER if f"\n  {g}:" in body] == list(GROUP_ORDER)
    for name, p in _subparsers(build_parser()).items():
        assert p.description, name
    with pytest.raises(SystemExit):
        main(["--version"])
    assert capsys.readouterr().out.strip() == f"asphalt-nscd {__version__}"
    run = subprocess.run([sys.executable, "-m", "asphalt_nscd", "--version"], capture_output=True, text=True)
    assert run.returncode == 0 and run.stdout.strip() == f"asphalt-nscd {__version__}"
