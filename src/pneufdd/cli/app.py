"""The ``pneufdd`` command. Each sub-command lives in its own module with a ``register``."""

from __future__ import annotations

import sys
from typing import Annotated

import typer
from rich.console import Console

from pneufdd import __version__
from pneufdd.cli import campaign, demo, diagnose, features, machine, reference, simulate, steps
from pneufdd.cli import history as history_cli
from pneufdd.cli import monitor as monitor_cli
from pneufdd.cli.exit_codes import ExitCode
from pneufdd.errors import InputError, PneufddError

__all__ = ["app", "main"]

app = typer.Typer(
    name="pneufdd",
    help="Find, locate, size and cost compressed-air leaks in sequenced pneumatic machines.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

for module in (demo, simulate, machine, steps, features, reference, diagnose, campaign):
    module.register(app)
for module in (monitor_cli, history_cli):
    module.register(app)


@app.callback(invoke_without_command=True)
def _root(
    version: Annotated[bool, typer.Option("--version", help="Print the version and exit.")] = False,
) -> None:
    if version:
        typer.echo(__version__)
        raise typer.Exit(ExitCode.OK)


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; map library errors to documented exit codes (see exit_codes)."""
    err = Console(stderr=True)
    try:
        # In non-standalone mode click returns a raised typer.Exit's code as the value.
        returned = app(args=argv, standalone_mode=False)
    except InputError as exc:
        err.print(f"[bold red]error:[/] {exc}", highlight=False)
        return ExitCode.INPUT_ERROR
    except PneufddError as exc:
        err.print(f"[bold red]error:[/] {exc}", highlight=False)
        return ExitCode.INPUT_ERROR
    except typer.Exit as exc:
        return int(exc.exit_code)
    except (typer.Abort, KeyboardInterrupt):
        err.print("aborted")
        return ExitCode.INPUT_ERROR
    except Exception as exc:  # click usage errors carry their own exit code
        code = getattr(exc, "exit_code", None)
        if code is not None:
            show = getattr(exc, "show", None)
            if callable(show):
                show()
            return int(code)
        raise
    return int(returned) if isinstance(returned, int) else ExitCode.OK


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
