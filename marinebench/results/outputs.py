"""Write one experiment's result directory atomically."""

from __future__ import annotations

from pathlib import Path

import yaml

from marinebench.experiments.runner import RunResult
from marinebench.plotting.figures import timeseries, tracking
from marinebench.provenance import inputs_key
from marinebench.results.claims import ClaimResult, manifest_entries
from marinebench.results.claims import evaluate as evaluate_claims
from marinebench.results.claims import markdown as claims_markdown
from marinebench.results.tables import markdown_table
from marinebench.results.writer import atomic_directory, manifest

_RK4 = "plant and observers integrated jointly by fixed-step RK4; dt refused unless dt*|lambda|max <= stiffness_limit"
STANDARD_ASSUMPTIONS = {
    "open_loop_asv": [
        ("Liu-Wang-Peng ESO reconstructed (LIU19 text unavailable): eps-scaled ESO, k=(3,3,1), linear corrections "
        "by default (shared/reference/baselines.md s.1)"),
        ("Bejarano LMIs with an added disk region |lambda| <= rho (default max(50, 5 delta)) because (16)/(28) are "
        "flat in the gains; time-scaled solve for delta >= 50 (baselines.md s.2.4)"),
        "true lumped disturbance sigma from eq. (6) with g = 0",
        _RK4,
    ],
    "dp_supply": [_RK4],
    "rov_tracking": [
        ("plant, CDO and EO integrated jointly by fixed-step RK4 at dt; sensors sampled and held, controllers "
        "discrete at control_period, commands through the thrust allocation and saturation"),
    ],
}


def _steps(worlds: dict) -> dict:
    """dt, horizon and steps of the world (or of each named world)."""
    info = {name: {"dt": sc.dt, "horizon": sc.horizon, "steps": round(sc.horizon / sc.dt)} for name, sc in worlds.items()}
    return next(iter(info.values())) if len(info) == 1 else {"scenarios": info}


def resolved_yaml(exp) -> str:
    """The experiment with every default filled in, as written to ``config.resolved.yaml``."""
    return yaml.safe_dump(exp.model_dump(mode="json"), sort_keys=False, allow_unicode=True)


def model_assumptions(worlds: dict) -> list[str]:
    """A DP world whose observers run on another vessel model than the plant says so."""
    return [f"scenario {w.name}: plant {w.vessel.kind}, observers designed and run on {w.model.kind} (model mismatch)"
            for w in worlds.values() if getattr(w, "design_vessel", None) not in (None, w.vessel)]


def write_run(result: RunResult, out_dir: Path, sources: dict[str, Path], claims: list[ClaimResult] | None = None) -> Path:
    """Write one experiment's result directory atomically (``claims``: its checked claims, if already
    evaluated; a config with ``claims:`` also gets ``claims.md``)."""
    exp = result.experiment
    if claims is None:
        claims = evaluate_claims(exp, result.metrics)
    with atomic_directory(out_dir) as tmp:
        (tmp / "config.resolved.yaml").write_text(resolved_yaml(exp))
        result.metrics.to_csv(tmp / "metrics.csv", index=False, float_format="%.6e")
        (tmp / "table.md").write_text(markdown_table(exp, result.summary))
        if claims:
            (tmp / "claims.md").write_text(claims_markdown(exp, claims))
        figdir = tmp / "figures"
        figdir.mkdir()
        for part in result.parts.values() or [result]:
            t, truth, est = part.traces
            variant, seed = part.run_variant[part.traced], part.run_seed[part.traced]  # the traces' columns
            for spec in part.experiment.figures:
                draw = tracking if spec.kind == "tracking" else timeseries
                draw(part.experiment, spec, t, truth, est, variant, seed, figdir / spec.file)
        worlds = {name: exp.part(name).scenario for name in exp.scenario_names}
        (tmp / "manifest.json").write_text(
            manifest(
                experiment=exp.name,
                inputs_key=inputs_key(exp),
                config_files={k or "experiment": str(v) for k, v in sources.items()},
                seed=exp.seed,
                seeds=exp.seeds,
                runs=len(result.run_seed),
                diverged_runs=int((result.metrics.groupby(["scenario", "variant", "seed"])["status"].first() != "ok").sum()),
                **_steps(worlds),
                max_observer_rate=result.max_rate,
                wall_time_s=round(result.wall_time, 3),
                assumptions=STANDARD_ASSUMPTIONS[worlds[exp.scenario_names[0]].kind] + model_assumptions(worlds)
                + list(exp.assumptions),
                designs=result.designs,
                claims=manifest_entries(claims),
            )
        )
    return out_dir
