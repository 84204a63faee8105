"""What the commands share: the typer ``app``, the options several take, the consoles, one-line errors and exit
codes, interruption, loading a config with the command line's options, and what ``run`` and ``sweep`` both
say about a result folder."""

from __future__ import annotations

import json
import re
import signal
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

from marinebench.errors import ConfigError, MarinebenchError

app = typer.Typer(add_completion=False, no_args_is_help=True, help="Simulation benchmarks for marine-vehicle observers.")
# options several commands take
Quiet = Annotated[bool, typer.Option("--quiet", "-q", help="no progress bar")]
DEFAULT_SWEEP = Path("configs/torben_fig3.yaml")  # relative to the working directory, as results/ is
SweepConfig = Annotated[Path, typer.Option(metavar="FILE", help="experiment with a sweep section (the default is relative to "
                                           "the working directory)")]
Sets = Annotated[list[str] | None, typer.Option("--set", metavar="KEY=VALUE", help="override a config field: "
                                                "dotted.key=value ('scenarios.*.horizon=20': * is every key or item)")]
ProfileName = Annotated[str | None, typer.Option("--profile", metavar="NAME", help="apply the config's named profile (e.g. quick)")]
Unpaired = Annotated[bool, typer.Option("--unpaired", help="compare the two sides as independent samples (e.g. runs on "
                                        "another --seed): every run counts, Welch's t interval (wider)")]
err = Console(stderr=True, highlight=False, soft_wrap=True)
out = Console(highlight=False, soft_wrap=True)


def progress_bar(label: str, quiet: bool) -> Progress:
    """``run``'s and ``sweep``'s bar on stderr: ``label``, the bar, the percentage, the time elapsed and the time
    left; it stays on screen when done, and ``--quiet`` disables it."""
    return Progress(TextColumn(label), BarColumn(), TextColumn("{task.percentage:>5.1f}%"), TimeElapsedColumn(),
                    TimeRemainingColumn(), console=err, disable=quiet)


def _print_version(value: bool) -> None:
    if value:
        from marinebench import __version__
        from marinebench.results.writer import git_revision

        revision = git_revision()
        out.print(f"marinebench {__version__}" + (f" (git {revision})" if revision != "unknown" else ""), markup=False)
        raise typer.Exit()


@app.callback()
def _options(version: Annotated[bool, typer.Option("--version", callback=_print_version, is_eager=True,
                                                   help="print the version (and git revision) and exit")] = False) -> None:
    """Simulation benchmarks for marine-vehicle observers."""


def fail(message: str, code: int = 2) -> None:
    """``message`` on one line of stderr (the lines of a message from a class of your own, or a library's, joined by
    " / "), and exit ``code``."""
    err.print(f"error: {one_line(message)}", markup=False)
    raise typer.Exit(code)


def one_line(message: str) -> str:
    """``message``'s non-blank lines, stripped and joined by " / "."""
    return " / ".join(line.strip() for line in message.splitlines() if line.strip())


class Terminated(KeyboardInterrupt):
    """SIGTERM (a cancelled CI job, ``timeout``, ``kill``), raised by the handler that :func:`marinebench.cli.main`
    installs (:func:`raise_terminated`) so that the command unwinds as on Ctrl-C: folders stay whole, the worker
    processes stop, the same line says what was kept."""


def raise_terminated(signum, frame) -> None:
    raise Terminated


def interrupted(what: str, exc: KeyboardInterrupt) -> None:
    """Ctrl-C or SIGTERM: say in one line what was kept and how to go on; exit 130 or 143 as the shell would
    (typer exits 130 silently)."""
    err.print(f"interrupted: {what}", markup=False)
    raise typer.Exit(128 + (signal.SIGTERM if isinstance(exc, Terminated) else signal.SIGINT))


@contextmanager
def one_line_errors() -> Iterator[None]:
    """A :class:`MarinebenchError` raised inside becomes its one line on stderr and exit code 2."""
    try:
        yield
    except MarinebenchError as exc:
        fail(str(exc))


def check_sweep_config(config: Path) -> None:
    """sweep/bench: the default --config is relative to the working directory; say so when it is not there."""
    if config == DEFAULT_SWEEP and not config.exists():
        fail(f"{config}: file not found in {Path.cwd()}: the default --config is relative to the working directory; "
             "run from the repository's root or pass --config FILE")


def load_config(config: Path, sets: list[str], seed: int | None, seeds: int | None, profile: str | None = None,
                sweep_params: bool = True, variants: str | None = None, traces: bool = False,
                inline: dict[str, tuple[str, str]] | None = None):
    """Load, validate and design (LMIs) one experiment; raises ConfigError naming file and key (``sweep_params``:
    see :func:`~marinebench.loading.load_checked`; ``variants``: ``sweep --variants``, comma-separated; ``traces``:
    ``run --traces``; ``inline``: the sweep parameters given in place, ``{key: (argument, value)}``,
    :func:`~marinebench.experiments.sweep.inline_params`). An error in what an option set names the option."""
    from marinebench.loading import load_checked

    if variants is not None:
        names = [name.strip() for name in variants.split(",")]
        if not all(names):
            raise ConfigError("--variants", "", f"comma-separated variant names, e.g. rise,srise, or 'all' (got '{variants}')")
        variants = json.dumps(names)  # quoted: a variant may be named "1e3"
    options = {"seed": ("--seed", seed), "seeds": ("--seeds", seeds), "sweep.variants": ("--variants", variants),
               "engine.write_traces": ("--traces", "true" if traces else None), **(inline or {})}
    sets = list(sets) + [f"{key}={value}" for key, (_, value) in options.items() if value is not None]
    try:
        return load_checked(config, sets, profile, sweep_params)
    except ConfigError as exc:  # the options are applied last, as --sets: name the option that was typed
        key = next((k for k in options if exc.key == k or exc.key.startswith(f"{k}.")), None)
        if exc.file == "--set" and key is not None and options[key][1] is not None:
            raise ConfigError(options[key][0], "", exc.message) from None
        raise


def diverged_warning(name: str, metrics) -> str | None:
    """The warning that some runs diverged (their metric values are excluded from means, tables and claims)."""
    n_div = int((metrics["status"] != "ok").sum())
    return f"warning: {name}: {n_div} metric values from diverged runs excluded" if n_div else None


def claims_verdict(required: bool, failing: int) -> None:
    """``--require-claims``: exit 1, after everything is written, when any claim fails."""
    if required and failing:
        err.print(f"{failing} claim(s) fail (see claims.md)", markup=False)
        raise typer.Exit(1)


def output_stem(config: Path) -> str:
    """What a config's result folder is named after: the file's stem, or for a result folder's
    ``config.resolved.yaml`` the experiment's ``name`` in it, so that rerunning a result writes where the config it
    was resolved from did (``results/torben_fig1/``), not to ``config.resolved/``."""
    if config.name == "config.resolved.yaml":
        from marinebench.config import NAME
        from marinebench.loading import read_yaml

        try:
            name = read_yaml(config).get("name")
        except ConfigError:  # loading the file reports it, naming the key
            name = None
        if isinstance(name, str) and re.fullmatch(NAME, name):
            return name
    return config.stem


def up_to_date(exp, target: Path, quiet: bool) -> int | None:
    """``--resume``: None when ``target`` was not written from the same inputs as ``exp`` (its manifest's
    ``inputs_key``), or its manifest cannot be read (then it is written again); otherwise says so and returns the
    number of failing claims the manifest records."""
    from marinebench.provenance import inputs_key
    from marinebench.results.stored import StoredResultError, read_manifest

    try:
        stored = read_manifest(target)
    except (OSError, StoredResultError):
        return None
    if stored.get("inputs_key") != inputs_key(exp):
        return None
    claims = stored.get("claims", [])
    if not quiet:
        verdict = f", {sum(c['holds'] for c in claims)} of {len(claims)} claims hold" if claims else ""
        out.print(f"{exp.name}: up to date (same inputs){verdict} -> {target}", markup=False)
    return sum(not c["holds"] and "not_checked" not in c for c in claims)


def check_points(n: int | None, horizon: float | None) -> None:
    """sweep, bench: ``--n`` points per parameter and ``--horizon`` seconds per run in range."""
    from marinebench.experiments.sweep import points_error

    if bad := points_error(n, horizon):
        fail(f"--{bad[0]}: must be {bad[1]}")
