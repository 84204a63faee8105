"""Shared fixtures: small, fast configs written to tmp paths."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest
import yaml

from marinebench.results.tables import md_split

ROOT = Path(__file__).resolve().parents[1]
TORBEN_FIG3 = ROOT / "configs" / "torben_fig3.yaml"


def sorted_values(frame) -> list[float]:
    """A tidy metrics frame's values in a fixed order (variant, seed, signal, metric), to compare two runs of
    the same sweep wherever their batches ran."""
    return frame.sort_values(["variant", "seed", "signal", "metric"])["value"].tolist()


def md_row(table: str, *cells: str) -> list[str]:
    """The cells of the first row of a markdown ``table`` that starts with ``cells``."""
    for line in table.splitlines():
        parts = md_split(line)
        if parts[: len(cells)] == list(cells):
            return parts
    raise AssertionError(f"no row {cells} in\n{table}")


def accepts_and_refuses(model, base: dict, ok: list[dict], bad: list[dict]) -> None:
    """``model(**base, **settings)`` builds for every settings dict of ``ok`` and, for every one of ``bad``, raises a
    ValidationError that names the setting's key."""
    from pydantic import ValidationError

    for settings in ok:
        model(**{**base, **settings})
    for settings in bad:
        with pytest.raises(ValidationError, match=next(iter(settings))):
            model(**{**base, **settings})


def write_tiny(directory: Path, horizon: float = 4.0) -> Path:
    """A short noisy experiment with two variants, two seeds, a table and two figures."""
    doc = {
        "description": "tiny",
        "scenario": {"from": str(ROOT / "scenarios" / "cs2_noisy.yaml"), "horizon": horizon, "dt": 0.01},
        "seeds": 2,
        "variants": [
            {"name": "liu_eps0.2", "observer": {"kind": "liu_eso", "eps": 0.2}},
            {"name": "proposed_d1.2", "observer": {"kind": "bejarano", "delta_psi1": 1.2, "delta_p1": 1.2, "k_n": 1}},
        ],
        "metrics": [{"kind": "std", "t_start": 1.0}],
        "table": {"title": "tiny", "metric": "std", "signals": ["u", "sigma_u"],
                  "paper": {"source": "nobody", "values": {"liu_eps0.2": {"u": 0.09}}}},
        "figures": [{"file": "u.png", "signals": ["u"]}, {"file": "sv.png", "signals": ["sigma_v"]}],
    }
    path = directory / "tiny.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


@pytest.fixture
def tiny_config(tmp_path: Path) -> Path:
    """A 4-s noisy experiment (runs in about a second)."""
    return write_tiny(tmp_path)


def tidy_metrics(values: dict, experiment: str = "exp", scenario: str = "scen", status: dict | None = None,
                 metric: str = "std") -> pd.DataFrame:
    """A tidy metrics frame of one ``metric``: values[(variant, signal)] -> per-seed values (seed = position), with
    status[(variant, signal, seed)] where a run is not 'ok'."""
    rows = [(experiment, scenario, v, seed, s, metric, x, (status or {}).get((v, s, seed), "ok"))
            for (v, s), vals in values.items() for seed, x in enumerate(vals)]
    return pd.DataFrame(rows, columns=["experiment", "scenario", "variant", "seed", "signal", "metric", "value", "status"])
