"""The ``pneufdd`` command. Each sub-command lives in its own module with a ``register``.

Command modules import only typer, rich and :mod:`pneufdd.errors` at module level; the
subsystem a command needs is imported inside the command function, so ``pneufdd
--help`` and light commands start fast (``benchmarks/bench_startup.py``).
"""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING, Annotated

import typer

from pneufdd import __version__
from pneufdd.cli import (
    build_twin,
    campaign,
    commission,
    demo,
    diagnose,
    energy,
    evaluate,
    features,
    history,
    import_data,
    machine,
    monitor,
    reference,
    serve,
    simulate,
    standstill,
    steps,
    users,
)
from pneufdd.cli.exit_codes import ExitCode
from pneufdd.errors import InputError, PneufddError

if TYPE_CHECKING:
    from rich.console import Console

__all__ = ["app", "main"]

app = typer.Typer(
    name="pneufdd",
    help="Find, locate, size and cost compressed-air leaks in sequenced pneumatic machines.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
)

for module in (demo, simulate, machine, steps, features, reference, diagnose, campaign):
    module.register(app)
for module in (
    import_data,
    evaluate,
    monitor,
    history,
    serve,
    users,
    build_twin,
    standstill,
    energy,
    commission,
):
    module.register(app)

_STATE = {"debug": False}


@app.callback(invoke_without_command=True)
def _root(
    version: Annotated[bool, typer.Option("--version", help="Print the version and exit.")] = False,
    debug: Annotated[
        bool,
        typer.Option("--debug", help="On an internal error, show the full traceback."),
    ] = False,
) -> None:
    _STATE["debug"] = debug
    if version:
        typer.echo(__version__)
        raise typer.Exit(ExitCode.OK)


def _app_for(args: list[str]) -> typer.Typer:
    """The app, holding only the command ``args`` invoke (building all costs ~0.1 s).

    Typer builds every registered command (with its parameter converters) before
    parsing; ``pneufdd machines`` needs only its own. Without a command name (``--help``,
    ``--version``) or with an unknown one (click then lists the commands) the full app
    answers.
    """
    name = next((a for a in args if not a.startswith("-")), None)
    commands = [c for c in app.registered_commands if c.name == name]
    groups = [g for g in app.registered_groups if g.name == name]
    if name is None or not (commands or groups):
        return app
    single = typer.Typer(
        name="pneufdd",
        help=app.info.help,
        no_args_is_help=True,
        add_completion=False,
        pretty_exceptions_enable=False,
        rich_markup_mode=None,
    )
    single.callback(invoke_without_command=True)(_root)
    single.registered_commands = commands
    single.registered_groups = groups
    return single


def _stderr() -> Console:
    """The console errors are printed on (rich is imported only when one is)."""
    from rich.console import Console

    return Console(stderr=True)


def _error(text: str) -> None:
    """Print ``error: text`` on stderr, the text as written (no markup read in it)."""
    from rich.markup import escape

    from pneufdd.limits import clip_message

    _stderr().print(
        f"[bold red]error:[/] {escape(clip_message(text))}",
        highlight=False,
        markup=True,
        soft_wrap=True,
    )


def _internal_error(exc: BaseException) -> int:
    """Exit 3 with one line (the traceback with ``--debug``): a bug, never "leak found"."""
    from rich.markup import escape

    err = _stderr()
    if _STATE["debug"]:
        err.print_exception(show_locals=False)
    text = " ".join(str(exc).split())
    if len(text) > 200:
        text = text[:197] + "..."
    err.print(
        f"[bold red]internal error:[/] {type(exc).__name__}: {escape(text)} (a bug in "
        f"pneufdd {__version__}; run again as 'pneufdd --debug ...' for the traceback, and "
        "please report it)",
        highlight=False,
        markup=True,
        soft_wrap=True,
    )
    return ExitCode.INTERNAL_ERROR


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; map errors to the documented exit codes (see exit_codes).

    Bad input (:class:`~pneufdd.errors.InputError`, a file the system refuses to
    read or write, a click usage error) exits 2; any other exception is a bug and
    exits 3 with one line pointing to ``--debug``.
    """
    args = sys.argv[1:] if argv is None else list(argv)
    _STATE["debug"] = "--debug" in args[: args.index("--") if "--" in args else len(args)]
    try:
        # In non-standalone mode click returns a raised typer.Exit's code as the value.
        returned = _app_for(args)(args=args, standalone_mode=False, prog_name="pneufdd")
    except (InputError, PneufddError) as exc:
        _error(str(exc))
        return ExitCode.INPUT_ERROR
    except typer.Exit as exc:
        return int(exc.exit_code)
    except (typer.Abort, KeyboardInterrupt):
        _stderr().print("aborted")
        return ExitCode.INPUT_ERROR
    except OSError as exc:
        # the system refused a file the user named (permissions, a folder, a full disk)
        if getattr(exc, "filename", None) is None:
            return _internal_error(exc)
        name = str(exc.filename)
        shown = name if len(name) <= 200 else f"{name[:197]}..."  # one line, not 10,000 chars
        _error(f"{exc.strerror or type(exc).__name__}: {shown!r}")
        return ExitCode.INPUT_ERROR
    except Exception as exc:
        code = getattr(exc, "exit_code", None)
        show = getattr(exc, "show", None)
        if isinstance(code, int) and callable(show):  # click usage errors
            show()
            return code
        return _internal_error(exc)
    return int(returned) if isinstance(returned, int) else ExitCode.OK


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
