"""Every numeric option of every command declares its range, and refuses what it declares
refused in one line naming the option (exit code 2), before any file is read or work done."""

from __future__ import annotations

from collections.abc import Iterator

import click
import pytest

from mirror_avatar.cli import cli, main
from mirror_avatar.cli.constrained import ConstrainedEither, ConstrainedNumber


def commands(
    group: click.Group = cli, path: tuple[str, ...] = ()
) -> Iterator[tuple[tuple[str, ...], click.Command]]:
    """Yield every command of the command line with its words (``("group", "train")``)."""
    context = click.Context(group)
    for name in group.list_commands(context):
        command = group.get_command(context, name)
        assert command is not None
        if isinstance(command, click.Group):
            yield from commands(command, (*path, name))
        else:
            yield (*path, name), command


NUMERIC = [
    (words, option)
    for words, command in commands()
    for option in command.params
    if isinstance(option, click.Option)
    and isinstance(
        option.type, click.types.IntParamType | click.types.FloatParamType | ConstrainedNumber
    )
]
"""Every option of the command line that takes a number."""

EITHER = [
    (words, option)
    for words, command in commands()
    for option in command.params
    if isinstance(option, click.Option) and isinstance(option.type, ConstrainedEither)
]
"""Every option of the command line that takes a word or a number (``--symbols auto|N``)."""

REFUSALS = [
    pytest.param(words, option.opts[0], value, id=f"{' '.join(words)} {option.opts[0]}={value}")
    for words, option in NUMERIC + EITHER
    for value in (
        option.type.interval.refused()
        if isinstance(option.type, ConstrainedNumber)
        else option.type.either.refused()
        if isinstance(option.type, ConstrainedEither)
        else []
    )
]


def test_every_numeric_option_declares_its_range():
    undeclared = [
        f"{' '.join(words)} {option.opts[0]}"
        for words, option in NUMERIC
        if not isinstance(option.type, ConstrainedNumber | click.IntRange)
    ]
    assert not undeclared, f"options without a declared range: {undeclared}"
    assert len(REFUSALS) > 50


@pytest.mark.parametrize(("words", "flag", "value"), REFUSALS)
def test_a_refused_value_is_one_line_naming_the_option(capsys, words, flag, value):
    assert main([*words, flag, str(value)]) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and flag in error, error


@pytest.mark.parametrize(
    ("words", "flag", "value"),
    [(("study", "table"), "--surrogates", 100_000), (("study", "report"), "--resamples", 10**8)],
)
def test_a_count_beyond_its_range_is_refused_before_the_input_is_read(
    capsys, tmp_path, words, flag, value
):
    """``--resamples 1e8`` ran out of memory, ``--surrogates 100000`` failed late naming the
    internal ``n_surrogates``: both are refused at once, naming the option and its range."""
    out = tmp_path / "out"
    assert main([*words, str(tmp_path / "missing"), "--out", str(out), flag, str(value)]) == 2
    (error,) = capsys.readouterr().err.strip().splitlines()
    assert flag in error and "missing" not in error and "n_surrogates" not in error, error
    assert not out.exists()
