"""Every command's --help ends with an example that parses, and the shared options (--calib,
--marker, --robot, --plant, --registration, --json, --out, --image-scale) mean the same in
every command: one metavar and one help text (wristmark/cli/common_options.py)."""

from __future__ import annotations

import argparse
import re
import shlex

import pytest

from wristmark.cli.common_options import CONFIG_OPTIONS, JSON_FILE_HELP, JSON_FLAG_HELP
from wristmark.cli.main import COMMANDS, build_parser, main


def command_parser(name: str) -> argparse.ArgumentParser:
    parser = build_parser(name)
    (sub,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return sub.choices[name]


def all_parsers() -> list[tuple[str, argparse.ArgumentParser]]:
    """Every command's parser and its nested ones (``marker print``)."""
    out = []
    for name in COMMANDS:
        p = command_parser(name)
        out.append((name, p))
        for a in p._actions:
            if isinstance(a, argparse._SubParsersAction):
                out += [(f"{name} {k}", v) for k, v in a.choices.items()]
    return out


def examples(p: argparse.ArgumentParser) -> list[str]:
    assert p.epilog and p.epilog.startswith("example:\n"), "--help has no example"
    return [line.strip() for line in p.epilog.splitlines()[1:] if line.strip()]


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_help_ends_with_an_example_that_parses(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    p = command_parser(name)
    lines = examples(p)
    assert lines
    for line in lines:
        argv = shlex.split(line)
        assert argv[:2] == ["wristmark", name], line
        args = build_parser(name).parse_args(argv[1:])  # a bad example exits 2 here
        assert args.command == name
    with pytest.raises(SystemExit) as stop:
        main([name, "--help"])
    assert stop.value.code == 0
    shown = [ln.strip() for ln in capsys.readouterr().out.splitlines() if ln.strip()]
    assert shown[-len(lines):] == lines
    assert shown[-len(lines) - 1] == "example:"


def test_nested_commands_have_examples_too() -> None:
    nested = [(n, p) for n, p in all_parsers() if " " in n]
    assert [n for n, _ in nested] == ["marker print", "marker family"]
    for name, p in nested:
        for line in examples(p):
            assert line.startswith(f"wristmark {name} ")
            build_parser(name.split()[0]).parse_args(shlex.split(line)[1:])


def shared_actions() -> list[tuple[str, str, argparse.Action]]:
    out = []
    for name, p in all_parsers():
        for a in p._actions:
            for o in a.option_strings:
                if o in (*CONFIG_OPTIONS, "--json", "--out", "--image-scale"):
                    out.append((name, o, a))
    return out


def test_the_shared_options_are_found_in_many_commands() -> None:
    seen: dict[str, set[str]] = {}
    for name, option, _ in shared_actions():
        seen.setdefault(option, set()).add(name)
    assert {o: len(v) >= 4 for o, v in seen.items()} == {o: True for o in seen}
    assert set(seen) == {*CONFIG_OPTIONS, "--json", "--out", "--image-scale"}


@pytest.mark.parametrize("option", sorted(CONFIG_OPTIONS))
def test_config_options_mean_the_same(option: str) -> None:
    metavar, text = CONFIG_OPTIONS[option]
    for name, o, a in shared_actions():
        if o == option:
            assert a.metavar == metavar, f"{name} {option}: metavar {a.metavar}"
            assert a.help is not None and a.help.startswith(text), f"{name} {option}: {a.help}"
            assert a.nargs is None and a.type is None  # one path (or a LEFT,RIGHT pair)


def test_json_is_a_flag_or_a_json_file() -> None:
    flag_prefix, flag_suffix = JSON_FLAG_HELP.split("{what}")
    file_prefix, file_suffix = JSON_FILE_HELP.split("{what}")
    for name, o, a in shared_actions():
        if o != "--json":
            continue
        assert a.help is not None
        if a.nargs == 0:
            assert a.help.startswith(flag_prefix) and a.help.endswith(flag_suffix), f"{name}: {a.help}"
        else:
            assert name in ("servo", "experiment"), f"{name}: --json takes a value"
            assert a.metavar == "FILE.json" and a.help.startswith(file_prefix) and a.help.endswith(file_suffix)


def test_out_names_a_folder_or_a_file() -> None:
    for name, o, a in shared_actions():
        if o != "--out":
            continue
        assert a.help is not None
        if a.metavar == "DIR":
            assert a.help.startswith("output folder"), f"{name}: {a.help}"
        else:
            assert re.fullmatch(r"FILE\.[a-z]+", str(a.metavar)), f"{name}: metavar {a.metavar}"
            assert a.help.startswith("output file"), f"{name}: {a.help}"


def test_image_scale_is_a_validated_factor() -> None:
    for name, o, a in shared_actions():
        if o == "--image-scale":
            assert a.metavar == "F", name
            assert getattr(a.type, "__name__", "") == "number", name  # cli.option_types, never bare float
            with pytest.raises(argparse.ArgumentTypeError):
                a.type("0")  # type: ignore[misc]


def test_render_takes_image_scale_like_every_command() -> None:
    for flag in ("--image-scale", "--scale"):  # --scale: its old name
        args = build_parser("render").parse_args(["render", "--out", "x", flag, "0.5"])
        assert args.scale == 0.5
