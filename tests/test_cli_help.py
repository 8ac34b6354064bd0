"""Every ``fidlearn ... --help`` reads as plain text with one way of naming each placeholder.

The help is argparse's, printed in a terminal: reST markup (````literal````, ``:func:``) would
be shown as it is written, so none may appear. Placeholders (metavars) are capitals, one name
per option across the commands, and the unit options name their unit (``--square-mm MM``).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import re
import shlex

import pytest

from fidlearn.cli import build_parser, main

#: reST that a terminal would show raw: ``literal``, :role:`x`, `link`_ and .. directive::
REST = re.compile(r"``|:[a-z]+:`|`_\b|^\s*\.\. [a-z-]+::", re.M)
#: A placeholder: capitals, digits and _ , separated by , | or x between capitals (WxH, CxR, X,Y,Z),
#: and may end in a file extension (MAP.json, CAMERA_INFO.yaml).
PLACEHOLDER = re.compile(r"[A-Z][A-Z0-9_]*(?:(?:x|,|\|)[A-Z][A-Z0-9_]*)*(?:\.[a-z]+)?")
#: Options whose metavar is their unit, whatever the command.
UNIT_METAVARS = {"-mm": "MM", "-deg": "DEG", "-px": "PX", "-mb": "MB"}
#: -o names the file each command writes; every other option has one metavar across all commands.
PER_COMMAND = {"-o", "--output"}


def _subparsers(parser: argparse.ArgumentParser, prefix: tuple[str, ...] = ()):
    """(command words, parser) for the top parser and every subcommand, depth first."""
    yield prefix, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, child in action.choices.items():
                yield from _subparsers(child, (*prefix, name))


COMMANDS = list(_subparsers(build_parser()))


def _help(words: tuple[str, ...]) -> str:
    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit) as stop:
        main([*words, "--help"])
    assert stop.value.code == 0
    return out.getvalue()


def test_every_command_is_walked():
    names = {" ".join(words) for words, _ in COMMANDS}
    for expected in ("", "board", "calibrate", "camera export", "camera import", "locate", "plan", "grade", "doctor"):
        assert expected in names
    assert len(names) >= 15


@pytest.mark.parametrize("words", [w for w, _ in COMMANDS], ids=lambda w: " ".join(w) or "fidlearn")
def test_help_has_no_rest_markup(words):
    text = _help(words)
    assert text.startswith("usage: fidlearn")
    assert REST.findall(text) == [], text


def _metavars(parser: argparse.ArgumentParser):
    for action in parser._actions:
        if action.nargs == 0 or isinstance(action, (argparse._HelpAction, argparse._SubParsersAction)):
            continue
        if action.choices is not None and action.metavar is None:
            continue  # {a4,letter}: the choices themselves
        metavar = action.metavar or (action.dest.upper() if action.option_strings else action.dest)
        yield action, metavar if isinstance(metavar, str) else " ".join(metavar)


def test_placeholders_are_capitals():
    bad = [
        (" ".join(words), action.option_strings or action.dest, metavar)
        for words, parser in COMMANDS
        for action, metavar in _metavars(parser)
        if not PLACEHOLDER.fullmatch(metavar)
    ]
    assert bad == []


def test_unit_options_name_their_unit():
    bad = []
    for words, parser in COMMANDS:
        for action, metavar in _metavars(parser):
            for option in action.option_strings:
                unit = next((m for end, m in UNIT_METAVARS.items() if option.endswith(end)), None)
                if unit is not None and metavar != unit:
                    bad.append((" ".join(words), option, metavar))
    assert bad == []


def test_one_placeholder_per_option_across_commands():
    seen: dict[str, dict[str, list[str]]] = {}
    for words, parser in COMMANDS:
        for action, metavar in _metavars(parser):
            for option in set(action.option_strings) - PER_COMMAND:
                seen.setdefault(option, {}).setdefault(metavar, []).append(" ".join(words))
    assert {option: uses for option, uses in seen.items() if len(uses) > 1} == {}
    assert len(seen["--camera"]) == 1
    assert len(seen["--map"]) == 1
    assert "--image-size" in seen


def test_the_checks_see_what_they_refuse():
    assert REST.findall("see ``fidlearn plan`` and :func:`locate` or `docs`_") == ["``", "``", ":func:`", "`_"]
    assert REST.findall("a 'quoted' word, 9x6 inner corners, -o OUT.png") == []
    for good in ("MM", "MAP.json", "WxH", "CxR", "X,Y,Z,ROLL,PITCH,YAW", "CAMERA_INFO.yaml", "POSES.jsonl", "N"):
        assert PLACEHOLDER.fullmatch(good), good
    for bad in ("map", "notebooks", "Mm", "camera.json", "OUT/<learner>", "MAP.JSON x"):
        assert not PLACEHOLDER.fullmatch(bad), bad


def test_options_explained_below_the_list_use_their_placeholder():
    """``--mount MOUNT.json   where the camera sits``: the epilog names an option's value as the option list does."""
    checked = 0
    for words, parser in COMMANDS:
        metavars = {o: m for action, m in _metavars(parser) for o in action.option_strings}
        for line in _help(words).splitlines():
            m = re.match(r"^\s*(--[\w-]+) (\S+)\s{2,}\S", line)
            if m and m[1] in metavars:
                # an optional value shows in brackets (``--live [PORT]``): the placeholder is the same
                assert m[2].removeprefix("[").removesuffix("]") == metavars[m[1]], (" ".join(words), line)
                checked += line.lstrip() == line or m[1] == "--pose"  # written in an epilog
    assert checked >= 2


def test_the_examples_in_the_top_help_are_valid_command_lines():
    """``fidlearn --help`` ends with the pipeline as commands: each one parses (names of the user's own files)."""
    examples = [line.split("  ")[1].strip() for line in _help(()).splitlines() if line.startswith("  fidlearn ")]
    assert len(examples) >= 6
    for example in examples:
        args = build_parser().parse_args(shlex.split(example)[1:])
        assert callable(args.run), example
