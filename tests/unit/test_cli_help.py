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
