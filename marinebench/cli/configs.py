"""The commands that read configs and the registry without simulating: ``validate``, ``design``,
``schema`` and ``list``."""

from __future__ import annotations

import json
import sys
from enum import Enum
from pathlib import Path
from typing import Annotated

import typer

from marinebench.cli.common import ProfileName, Sets, err, fail, load_config, one_line_errors, out
from marinebench.errors import ConfigError


def validate(
    files: Annotated[list[Path], typer.Argument(metavar="FILE", help="experiment or scenario YAML files")],
    set_: Sets = None,
    profile: ProfileName = None,
) -> None:
    """Check configs (and solve their observer designs) without running them.

    With --set and --profile, each file is checked as run would load it."""
    from marinebench.loading import is_scenario_file, load_scenario

    for f in files:
        with one_line_errors():
            if is_scenario_file(f):
                if set_ or profile:
                    raise ConfigError("--set" if set_ else "--profile", "", f"{f}: a scenario file; --set and --profile "
                                      "apply to experiment files (which can set scenario.<key>)")
                load_scenario(f)
            else:
                exp, _ = load_config(f, set_ or [], None, None, profile)
                for i, claim in enumerate(exp.claims):
                    if (problem := exp.claim_problem(claim)) is not None:
                        err.print(f"warning: {f}: claims.{i} cannot be checked: {problem}", markup=False)
        out.print(f"{f}: ok", markup=False)


def design(
    files: Annotated[list[Path], typer.Argument(metavar="CONFIG", help="experiment YAML files")],
    set_: Sets = None,
    profile: ProfileName = None,
    as_json: Annotated[bool, typer.Option("--json", help="JSON instead of YAML")] = False,
) -> None:
    """Solve and print each variant's observer design (gains, poles) without simulating.

    LMI gains and poles (Bejarano, the CDO's K*), Kalman gains L1/L2 (Torben), ESO gains, as the manifest records
    them. With --set, e.g. scenario.cdo.lmi_decay=0.2, a design is recomputed for other settings."""
    import yaml

    from marinebench.experiments.runner import designs as designs_of

    designs = {}
    for f in files:
        with one_line_errors():
            exp, _ = load_config(f, set_ or [], None, None, profile)
            parts = {name: designs_of(exp.part(name)) for name in exp.scenarios} if exp.scenarios else None
            designs[exp.name] = parts or designs_of(exp)
    plain = json.loads(json.dumps(designs, default=float))  # numpy scalars -> floats
    if as_json:
        sys.stdout.write(json.dumps(plain, indent=2) + "\n")
    else:
        sys.stdout.write(yaml.safe_dump(_rounded(plain), sort_keys=False, default_flow_style=None, width=120,
                                        allow_unicode=True))


def _rounded(obj, digits: int = 6):
    """Floats in a nested document to ``digits`` significant digits (for reading; --json keeps them all)."""
    if isinstance(obj, float):
        return float(f"{obj:.{digits}g}")
    if isinstance(obj, dict):
        return {k: _rounded(v, digits) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_rounded(v, digits) for v in obj]
    return obj


class FileKind(str, Enum):
    experiment = "experiment"
    scenario = "scenario"


def schema(kind: Annotated[FileKind, typer.Option(help="which files")] = FileKind.experiment) -> None:
    """Print the JSON Schema of experiment (or scenario) YAML files, for editor completion and checking.

    The schema is of the files as written: with from:, and scenario paths."""
    from marinebench.schema import file_schema

    sys.stdout.write(json.dumps(file_schema(kind.value), indent=2) + "\n")


def list_kinds(
    groups: Annotated[list[str] | None, typer.Argument(metavar="GROUP|KIND", help="only these groups, e.g. observers "
                                                        "metrics (default: all); a kind, e.g. bejarano, lists its "
                                                        "settings", show_default=False)] = None,
) -> None:
    """List registered kinds: scenarios, vessels, observers, controllers, signals, noise, events, metrics.

    Each observer shows the scenario kinds it runs on. `marinebench list observers` lists one group;
    `marinebench list bejarano` lists one kind's settings (the keys of its YAML mapping, and what a sweep's KEY may
    name), with type, default and meaning; a scenario kind's also the signals its metrics and figures may name."""
    from marinebench.keypaths import did_you_mean, near_misses
    from marinebench.registry import kind_models, kinds

    registered, models = kinds(), kind_models()
    named = {kind for entries in models.values() for kind in entries}
    for group in groups or []:
        if group not in registered and group not in named:
            fail(f"GROUP: no group or kind '{group}'{did_you_mean(near_misses(group, [*registered, *sorted(named)]))}; "
                 f"groups: {', '.join(registered)}")
    for group, entries in registered.items():
        if groups and group not in groups:
            continue
        out.print(f"[bold]{group}[/bold]")
        for name, doc in entries.items():
            out.print(f"  {name:<22} {doc}", markup=False)
    for kind in [g for g in groups or [] if g in named and g not in registered]:
        _print_settings(kind, registered, models)


def _print_settings(kind: str, registered: dict, models: dict) -> None:
    """``list KIND``: each group's model of that kind, its settings one per line."""
    from rich.markup import escape

    from marinebench.registry import fields_of

    for group, entries in models.items():
        if kind not in entries:
            continue
        out.print(f"[bold]{kind}[/bold] ({group}): {escape(registered[group][kind])}")
        only = getattr(entries[kind], "ONLY_FOR", {})  # a model read by several kinds: this kind's settings
        rows = [row for row in fields_of(entries[kind]) if kind in only.get(row[0], (kind,))]
        width = max((len(name) for name, *_ in rows), default=0)
        for name, type_, default, text in rows:
            out.print(f"  {name:<{width}}  {type_} = {default}" + (f"  {text}" if text else ""), markup=False)
        if signals := getattr(entries[kind], "SIGNALS", {}):
            out.print("  [bold]signals[/bold] (what a metric's or figure's signals: may name; est - truth):")
            width = max(map(len, signals))
            for name, text in signals.items():
                out.print(f"  {name:<{width}}  {text}", markup=False)
