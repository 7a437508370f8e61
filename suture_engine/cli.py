"""The ``suture`` command.

Each sub-command is a thin wrapper: it parses arguments with typer and hands
over to a function in the module that owns the work, imported lazily so that
start-up stays fast. Exit codes: 0 success, 1 the input is invalid or the run
failed, 2 usage or I/O errors. No command ever prints a traceback for bad
input.
"""

from __future__ import annotations

import typer

__all__ = ["app", "main"]

app = typer.Typer(
    name="suture",
    help="Run robotic suturing procedures written in YAML on simulated EndoBots.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def main() -> None:
    """Entry point of the ``suture`` console script."""
    app()


if __name__ == "__main__":  # pragma: no cover
    main()
