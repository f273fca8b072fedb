"""Every numeric option of every command is validated where it is parsed (issue 17, item 3).

The options are found from the argparse parsers of all commands in ``wristmark.cli.main.COMMANDS``, so
options added later are covered too. Bad values (NaN, +-inf, zero, negative, huge) end with
exit status 2 and one line on stderr; values the parser accepts run normally: never exit 1,
never a traceback, never a NaN in a result.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import re
import tempfile
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, assume, event, given, settings
from hypothesis import strategies as st

from wristmark.cli import main as cli

# A value-taking option whose metavar or help names one of these is numeric even without a type.
NUMERIC_METAVARS = {"S", "N", "PX", "F", "Q", "X", "Y", "Z", "HZ", "FPS", "M", "MM", "DEG", "RAD", "KB"}
UNIT_IN_HELP = re.compile(r"\[(s|ms|m|mm|px|N|Hz|rad|deg|N m|N\*m/rad)\]")

SPECIAL = ["nan", "NaN", "inf", "-inf", "+inf", "Infinity", "0", "-0", "0.0", "-1", "-5", "-0.5", "1e308",
           "-1e308", "1e-320", "9" * 30, "-" + "9" * 30, "1e30", "65536", "4294967296", "2.5", "1", "0.06"]
values = st.one_of(
    st.sampled_from(SPECIAL),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(min_value=-(10**40), max_value=10**40).map(str),
)


def command_parsers() -> dict[str, argparse.ArgumentParser]:
    """The sub-parser of every command, with its arguments added."""
    out = {}
    for name in cli.COMMANDS:
        parser = cli.build_parser(name)
        sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        out[name] = sub.choices[name]
    return out


PARSERS = command_parsers()


def _takes_values(a: argparse.Action) -> bool:
    return isinstance(a, argparse._StoreAction | argparse._AppendAction) and a.nargs != 0


def _looks_numeric(a: argparse.Action) -> bool:
    if a.type in (int, float, complex) or hasattr(a.type, "validated_range"):
        return True
    metavars = a.metavar if isinstance(a.metavar, tuple) else (a.metavar,)
    if a.type is None and any(str(m).upper() in NUMERIC_METAVARS for m in metavars if m):
        return True
    return a.type is None and bool(UNIT_IN_HELP.search(a.help or ""))


NUMERIC = [(cmd, a) for cmd, p in PARSERS.items() for a in p._actions if _takes_values(a) and _looks_numeric(a)]


def _name(a: argparse.Action) -> str:
    return a.option_strings[0] if a.option_strings else a.dest


def _accepts(a: argparse.Action, text: str) -> bool:
    try:
        a.type(text)  # type: ignore[misc]
        return True
    except (argparse.ArgumentTypeError, ValueError, TypeError):
        return False


def _filler(a: argparse.Action) -> str:
    """A value the option's type accepts (for the other entries of a list-valued option)."""
    if a.choices:
        return str(next(iter(a.choices)))
    if a.type is None or not hasattr(a.type, "validated_range"):
        return "x"
    for text in ("0", "1", "0.5", "2", "0.06", "10", "100", "1000", "0.01", "0.001"):
        if _accepts(a, text):
            return text
    raise AssertionError(f"no simple value is accepted by {_name(a)} {a.type.validated_range}")


def _count(a: argparse.Action) -> int:
    if isinstance(a.nargs, int):
        return a.nargs
    return 2 if a.nargs == "+" else 1


def _required_argv(cmd: str, skip: argparse.Action | None = None) -> list[str]:
    """Arguments the command cannot parse without (positionals and required options)."""
    argv: list[str] = []
    for a in PARSERS[cmd]._actions:
        if a is skip or not _takes_values(a):
            continue
        if not a.option_strings:
            argv += [_filler(a)] * _count(a)
        elif a.required:
            argv += [a.option_strings[0], *[_filler(a)] * _count(a)]
    return argv


def _option_argv(a: argparse.Action, text: str) -> list[str]:
    if not a.option_strings:
        return [text] * _count(a)
    if _count(a) == 1 and a.nargs is None:
        return [f"{a.option_strings[0]}={text}"]
    return [a.option_strings[0], text, *[_filler(a)] * (_count(a) - 1)]


def _parse(argv: list[str]) -> tuple[int | None, str, argparse.Namespace | None]:
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            ns = cli.build_parser(argv[0]).parse_args(argv)
        except SystemExit as e:
            return int(e.code or 0), err.getvalue(), None
    return None, err.getvalue(), ns


def _run(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = cli.main(argv)
        except SystemExit as e:
            code = int(e.code or 0)
    return code, out.getvalue(), err.getvalue()


def _assert_one_line_error(code: int | None, err: str, what: str) -> None:
    assert code == 2, f"{what}: exit {code}, stderr {err!r}"
    lines = err.strip().splitlines()
    assert len(lines) == 1, f"{what}: expected one line on stderr, got {err!r}"
    assert "Traceback" not in err and "internal error" not in err, err


def test_numeric_options_are_found() -> None:
    """The enumeration sees the options the issue names (it would otherwise test nothing)."""
    found = {(cmd, _name(a)) for cmd, a in NUMERIC}
    for expected in [("experiment", "--dt"), ("experiment", "--latency"), ("experiment", "--seed"),
                     ("experiment", "--image-scale"), ("experiment", "--positions"), ("experiment", "--forces"),
                     ("servo", "--settle"), ("servo", "--dt"), ("fk", "--psi"), ("render", "--pairs")]:
        assert expected in found


def test_every_numeric_option_uses_a_validated_type() -> None:
    """Each numeric option's type is one of cli/option_types.py (it names its range)."""
    bare = [f"{cmd} {_name(a)}" for cmd, a in NUMERIC if not hasattr(a.type, "validated_range")]
    assert not bare, "numeric options without a validated type (use cli/option_types.py): " + ", ".join(bare)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(option=st.sampled_from(NUMERIC), text=values)
def test_bad_numbers_are_refused_where_parsed(option: tuple[str, argparse.Action], text: str) -> None:
    cmd, a = option
    argv = [cmd, *_required_argv(cmd, skip=a), *_option_argv(a, text)]
    code, err, ns = _parse(argv)
    if code is not None:
        _assert_one_line_error(code, err, " ".join(argv))
        if _accepts(a, text) is False and (a.nargs is None or not text.startswith("-")):
            assert a.type.validated_range in err, f"the message should name the range: {err!r}"
        return
    assert ns is not None
    value = getattr(ns, a.dest)
    flat = value if isinstance(value, list) else [value]
    while flat and isinstance(flat[0], list):
        flat = [x for row in flat for x in row]
    assert all(math.isfinite(float(v)) for v in flat), f"{argv}: parsed a non-finite value {value}"


# null by design: no reprojection with --sensor truth-noise / not tracked / the reference sleeve
# carries no code (config.json marker.code) nor an arm name (marker.arm: one arm in view) / no
# --registration given
NOT_APPLICABLE = {"rms_px", "estimate", "code", "arm", "registration_world_T_left"}


def _no_nan(obj: Any, where: str) -> None:
    if isinstance(obj, dict):
        for k, v in obj.items():
            if not (k in NOT_APPLICABLE and v is None):
                _no_nan(v, f"{where}.{k}")
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            _no_nan(v, f"{where}[{i}]")
    else:
        assert obj is not None, f"{where} is null (NaN) in the result"
        if isinstance(obj, float):
            assert math.isfinite(obj), f"{where} = {obj}"


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(index=st.integers(0, 5), text=values)
def test_fk_runs_or_refuses(index: int, text: str) -> None:
    psi = ["0", "0.04", "0.7", "0", "0.9", "0"]
    psi[index] = text
    code, out, err = _run(["fk", "--psi", *psi, "--json"])
    if code != 0:
        _assert_one_line_error(code, err, f"fk --psi {psi}")
        return
    res = json.loads(out)
    _no_nan(res, "fk")
    assert len(res["jacobian"]) == 6


RUN_OPTIONS = ["--dt", "--latency", "--seed", "--image-scale", "--duration", "--positions", "--forces"]
CHEAP = {"--duration": 0.3, "--positions": 3, "--dt": 1.0}  # largest accepted value run for real (cost grows)


def _in_range(option: str) -> st.SearchStrategy[str]:
    """Accepted values of an experiment option (capped where the run's cost grows with them)."""
    a = next(x for x in PARSERS["experiment"]._actions if option in x.option_strings)
    lo, hi = a.type.bounds
    hi = min(hi, CHEAP.get(option, hi))
    if a.type.__name__ == "integer":
        return st.integers(int(lo), int(hi)).map(str)
    return st.floats(lo, hi).map(repr)


@pytest.mark.slow
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data(), option=st.sampled_from(RUN_OPTIONS))
def test_experiment_runs_or_refuses(data: st.DataObject, option: str) -> None:
    """Real (quick) experiment runs with values the parser accepts, and with bad ones."""
    text = data.draw(st.one_of(values, _in_range(option), _in_range(option)))
    name = {"--positions": "accuracy", "--forces": "load"}.get(option, "cube")
    a = next(x for x in PARSERS["experiment"]._actions if option in x.option_strings)
    if _accepts(a, text) and option in CHEAP:
        assume(float(text) <= CHEAP[option])
    with tempfile.TemporaryDirectory() as tmp:
        out_dir = Path(tmp) / "run"
        argv = ["experiment", name, "--sensor", "truth-noise", "--no-progress", "--out", str(out_dir),
                "--json", str(Path(tmp) / "result.json")]
        if option != "--duration":
            argv += ["--duration", "0.12"]
        if option != "--positions" and name == "accuracy":
            argv += ["--positions", "2"]
        argv += [f"{option}={text}"] if option != "--forces" else [option, text]
        code, out, err = _run(argv)
        event(f"{option}: {'ran' if code == 0 else 'refused'}")
        if code != 0:
            _assert_one_line_error(code, err, " ".join(argv))
            assert not out_dir.exists(), "a refused option must not leave a run folder"
            return
        assert "Traceback" not in err
        assert not re.search(r"\bnan\b", out, re.IGNORECASE), out
        _no_nan(json.loads((Path(tmp) / "result.json").read_text()), "result")
        configs = sorted(out_dir.rglob("config.json"))
        assert configs, f"no config.json under {out_dir}"
        for c in configs:
            _no_nan(json.loads(c.read_text()), str(c.relative_to(out_dir)))


def test_closed_pipe_ends_quietly(tmp_path: Path) -> None:
    """``wristmark fk --json | head -c 10``: exit 0 or 141 (SIGPIPE), nothing on stderr."""
    import subprocess
    import sys

    script = (
        "import os, sys\n"
        "r, w = os.pipe()\n"
        "os.close(r)\n"  # the reader is gone before anything is written
        "os.dup2(w, 1)\n"
        "from wristmark.cli import main as cli\n"
        "sys.exit(cli.main(['fk', '--psi', '0', '0.04', '0.7', '0', '0.9', '0', '--json']))\n"
    )
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60,
                       cwd=Path(__file__).resolve().parents[2])
    assert p.returncode in (0, 141), p.stderr
    assert p.stderr == "", p.stderr


@pytest.mark.parametrize("argv", [
    ["experiment", "cube", "--dt", "nan"],
    ["servo", "--settle", "nan"], ["experiment", "cube", "--seed", "-1"],
    ["experiment", "cube", "--image-scale", "inf"],
    ["experiment", "cube", "--dt", "inf"], ["experiment", "cube", "--latency", "nan"],
    ["experiment", "accuracy", "--positions", "-5"], ["experiment", "load", "--forces", "nan"],
    ["fk", "--psi", "nan", "0", "0", "0", "0", "0"],
])
def test_the_reported_cases_are_one_line_errors(argv: list[str], tmp_path: Path) -> None:
    code, out, err = _run([*argv, "--out", str(tmp_path / "o")] if argv[0] != "fk" else argv)
    _assert_one_line_error(code, err, " ".join(argv))
    assert not (tmp_path / "o").exists()
