"""marinebench command line: thin layer over config loading, the runner and the writers.

One module per command or family of commands (``run``, ``sweep``, ``bench``; ``results``: compare, report,
figures; ``configs``: validate, design, schema, list), registered on :data:`common.app` here, in the order
``--help`` lists them; :mod:`common` holds what they share.

Exit codes: 0 success, 1 failure of a check (``compare``; ``--require-claims``), 2 unusable input
(config errors, infeasible designs, a step too large for the observer gains).
"""

from __future__ import annotations

import inspect
import signal
import sys

import typer

from marinebench.cli import bench, configs, results, run, sweep
from marinebench.cli.common import Terminated, app, err, raise_terminated

__all__ = ["Terminated", "app", "main"]


def _help(command) -> str:
    """A command's help: its docstring with every paragraph on one line (typer's rich help keeps a docstring's line
    breaks, which the terminal then wraps a second time; the first paragraph is the summary in ``--help``)."""
    return "\n\n".join(" ".join(p.split()) for p in inspect.cleandoc(command.__doc__).split("\n\n"))


COMMANDS = {"run": run.run, "sweep": sweep.sweep, "bench": bench.bench, "compare": results.compare,
            "report": results.report, "figures": results.figures, "validate": configs.validate,
            "design": configs.design, "schema": configs.schema, "list": configs.list_kinds}  # in --help's order
for _name, _command in COMMANDS.items():
    app.command(_name, help=_help(_command))(_command)

# click's exception classes, through typer (recent typer vendors its own copy of click, older ones use click's)
_USAGE_ERROR, _CLICK_EXCEPTION = (next(c for c in typer.BadParameter.__mro__ if c.__name__ == name)
                                  for name in ("UsageError", "ClickException"))


def _command_named(args: list[str]) -> str:
    """``marinebench COMMAND`` for the command ``args`` name first (a usage error raised while its options are
    parsed may carry no context), else ``marinebench``."""
    names = typer.main.get_command(app).commands
    return f"marinebench {args[0]}" if args and args[0] in names else "marinebench"


def main(args: list[str] | None = None) -> None:
    """Console entry point: ``app``, except that a bad option or argument (a usage error, which typer draws as
    a boxed panel with the usage) is one line naming it, like every other input error, exit code 2; and SIGTERM
    is handled as Ctrl-C (:class:`Terminated`)."""
    signal.signal(signal.SIGTERM, raise_terminated)
    argv = sys.argv[1:] if args is None else args
    try:
        code = app(args=args, prog_name="marinebench", standalone_mode=False)
        if not argv:  # the help, a usage error (click >= 8.2 raises one; click 8.1 returned 0)
            code = 2
    except _USAGE_ERROR as exc:
        message = " ".join(exc.format_message().split()).replace(": Value error, ", ": ")  # typer checks via pydantic
        command = exc.ctx.command_path if exc.ctx else _command_named(argv)
        if message:  # (none when no arguments printed the help)
            err.print(f"error: {message} (see '{command} --help')", markup=False)
        sys.exit(2)
    except _CLICK_EXCEPTION as exc:
        exc.show()
        sys.exit(exc.exit_code)
    except typer.Abort:
        err.print("aborted", markup=False)
        sys.exit(1)
    sys.exit(code if isinstance(code, int) else 0)


