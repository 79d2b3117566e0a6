"""The command line's own errors (an unknown choice, a missing argument, an unknown option) are the project's one
line naming "command line" and the key, exit 2, not argparse's usage (issue 24 user findings); --help is
unchanged."""
from __future__ import annotations

import subprocess
import sys

import pytest
from conftest import assert_one_error_line

DAMAGE = ["damage", "clio", "--profile", "0.1,0.2", "--width", "1.0"]


@pytest.mark.parametrize("argv, key, words", [
    (DAMAGE + ["--side", "top"], "--side", ("invalid choice", "'top'", "crashlab damage --help")),
    (["damage", "clio", "--profile", "0.1,0.2"], "--side, --width", ("required",)),
    (["vehicles", "--bogus"], "--bogus", ("not an option", "crashlab vehicles --help")),
    (["simulate"], "scene", ("required", "crashlab simulate --help")),
    (["simulate", "x.toml", "--fps"], "--fps", ("expected one argument",)),
    (DAMAGE[:-1] + ["wide", "--side", "front"], "--width", ("invalid float value",)),
    (["stress", "--runs", "many"], "--runs", ("invalid int value",)),
    (["nosuch"], "COMMAND", ("invalid choice", "crashlab --help")),
    ([], "COMMAND", ("required",)),
    (["examples", "move", "x"], "action", ("invalid choice",)),
    (DAMAGE + ["--side", "front", "--wi", "1"], "--wi", ("ambiguous", "--width", "--with")),
])
def test_a_bad_command_line_is_one_line_naming_the_key(argv, key, words, capsys):
    from crashlab.cli import main
    with pytest.raises(SystemExit) as exc:
        main(argv)
    err = capsys.readouterr().err
    assert exc.value.code == 2
    assert "usage:" not in err and len(err.strip().splitlines()) == 1, err
    assert err.startswith(f"crashlab: error: command line: {key}: "), err
    for w in words:
        assert w in err, err


def test_the_installed_command_prints_one_line_and_keeps_its_help():
    res = subprocess.run([sys.executable, "-m", "crashlab.cli", "vehicles", "--bogus"], capture_output=True,
                         text=True, timeout=300)
    assert_one_error_line(res, "command line", "--bogus", ("crashlab vehicles --help",))
    res = subprocess.run([sys.executable, "-m", "crashlab.cli", "damage", "--help"], capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 0 and res.stdout.startswith("usage: crashlab damage") and "--restitution" in res.stdout


def test_every_subcommand_parser_gives_one_line():
    """Each subcommand's parser is the one-line kind (argparse makes it with its parent's class)."""
    from crashlab.cli import build_parser
    from crashlab.cli.main import OneLineParser, _subparsers
    parser = build_parser()
    subs = _subparsers(parser)
    assert len(subs) >= 12 and all(isinstance(p, OneLineParser) for p in [parser, *subs.values()])
