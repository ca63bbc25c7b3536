"""The CLI entry point: version and usage errors map to documented exit codes."""

from __future__ import annotations

from pneufdd import __version__
from pneufdd.cli.app import main


def test_version_exits_zero(capsys: object) -> None:
    assert main(["--version"]) == 0


def test_unknown_command_is_a_usage_error() -> None:
    assert main(["no-such-command"]) == 2


def test_version_string() -> None:
    assert __version__.count(".") == 2
