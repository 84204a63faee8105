"""Several variants swept side by side (``sweep --variants``, ``sweep.variants``): one curve each, their ratios and
where they cross, claims about ``sweep.variant`` only, and ``compare --variants`` point by point."""

import json

import numpy as np
import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

from marinebench.cli import app
from marinebench.config import SweepSpec
from marinebench.experiments.curves import crossings, sweep_claims, sweep_table

from .conftest import ROOT
from .conftest import md_row as row

TABLE4 = ROOT / "configs" / "bejarano_table4.yaml"
NOISE = ["--set", "sweep.params.noise={key: world.position_noise_scale, range: [0.0, 2.0]}"]


def flat(pairs: list[tuple[float, float]]) -> list[float]:
    return [v for pair in pairs for v in pair]


def test_crossings_are_linear_between_points_in_the_log_for_log_spacing_and_skip_gaps():
    x = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
    assert flat(crossings(x, np.array([0.5, 0.75, 1.25, 1.0, 0.5]))) == pytest.approx([1.5, 1.5, 3.0, 3.0])  # through, onto
    assert crossings(x, np.full(5, 2.0)) == [] and crossings(x, np.full(5, np.nan)) == []
    assert flat(crossings(x, np.array([0.5, np.nan, 1.5, 1.5, 1.5]))) == pytest.approx([1.0, 1.0])  # across a diverged point
    # a stretch on the level (to 1e-6: metrics.csv keeps 7 digits) is its first and last point
    assert crossings(x, np.array([0.5, 1.0, 1 - 1e-8, 1.0, 2.0])) == [(1.0, 3.0)]
    assert crossings(x, np.array([1.0, 1 + 2e-6, 1.0, 1.0, 1.0])) == [(0.0, 0.0), (2.0, 4.0)]
    # y = log10(x) / log10(3) on a log grid reaches 1 at x = 3 exactly when interpolated in log(x), not linearly
    g = np.geomspace(1, 16, 5)
    assert flat(crossings(g, np.log10(g) / np.log10(3.0), log=True)) == pytest.approx([3.0, 3.0])
    assert crossings(g, np.log10(g) / np.log10(3.0))[0][0] != pytest.approx(3.0)


def two_variants(seeds=(0, 1)) -> pd.DataFrame:
    """J = 10 - 5 k for variant 'p'; J = 4.5 + 5 k for 'q' (equal at k = 0.55); both at every k of 0..1."""
    rows = []
    for s in seeds:
        for v, f in (("p", lambda k: 10 - 5 * k), ("q", lambda k: 4.5 + 5 * k)):
            for k in np.linspace(0, 1, 11):
                rows.append((f"{v}_k_{round(10 * k):03d}_default", "k", k, v, s, f(k) * (1 + 0.01 * s)))
    df = pd.DataFrame(rows, columns=["variant", "param", "param_value", "sweep_variant", "seed", "value"])
    return df.assign(metric="J_tot", signal="z", status="ok", gnss="default")


SPEC = SweepSpec.model_validate({"variant": "p", "variants": ["p", "q"], "metric": "J_tot", "params": {"k": {"key": "k", "range": (0, 1)}},
                                 "claims": [{"kind": "trend", "param": "k", "range": (0, 1), "decreasing": True,
                                             "text": "J falls with k"}]})


def test_each_variant_is_a_curve_with_its_ratio_and_where_the_curves_meet():
    t = sweep_table(two_variants(), "J_tot", SPEC)
    assert "| param | variant | signal | points |" in t and "### Between variants" in t
    assert row(t, "k", "q", "z")[4:6] == [f"{4.5 * 1.005:.4g}", "0"]  # its minimum (the seed mean) at k = 0
    ratio = row(t, "k", "z", "q / p")
    assert ratio[3:7] == [f"{4.5 / 10:.3g}", "0", f"{9.5 / 5:.3g}", "1"]
    # the ratio (4.5 + 5k)/(10 - 5k) is not linear in k: interpolated between k = 0.5 and 0.6, near 0.55
    assert float(ratio[7]) == pytest.approx(0.55, abs=0.002) and float(ratio[7]) != 0.55
    # a third variant, twice p: its ratio to each earlier one
    m = two_variants()
    r = m[m["sweep_variant"] == "p"].assign(sweep_variant="r", value=lambda d: 2 * d["value"])
    t = sweep_table(pd.concat([m, r]), "J_tot", SPEC.model_copy(update={"variants": ["p", "q", "r"]}))
    assert "against each earlier one" in t and row(t, "k", "z", "r / p")[3:] == ["2", "0", "2", "0", "–"]
    assert row(t, "k", "z", "r / q")[3] == f"{10 / 9.5:.3g}" and row(t, "k", "z", "q / p")[7] == ratio[7]
    same = pd.concat([m, r.assign(value=lambda d: d["value"] / 2)])  # r identical to p
    assert row(sweep_table(same, "J_tot", SPEC), "k", "z", "r / p")[7] == "everywhere"
    apart = pd.concat([m, r.assign(value=lambda d: np.where(d["param_value"] > 0.55, d["value"], d["value"] / 2))])
    assert row(sweep_table(apart, "J_tot", SPEC), "k", "z", "r / p")[7] == "0–0.5"  # equal, then twice


def test_the_sweeps_claims_are_about_its_own_variant_only():
    """'p' falls with k, 'q' rises: the claim about sweep.variant 'p' holds and is checked on p's curve alone."""
    (res,) = sweep_claims(two_variants(), SPEC)
    assert res.holds and [c.where for c in res.checks] == ["default"]
    (res,) = sweep_claims(two_variants(), SPEC.model_copy(update={"variant": "q"}))
    assert not res.holds and res.checks[0].statistic == pytest.approx(1.0)


def test_a_groups_claim_may_compare_two_variants_swept_side_by_side():
    """'q above p at every k' fails below k = 0.55 (the lowest ratio, q/p = 0.45 at k = 0); 'p above q' fails above it;
    in a sweep of p alone neither is checked. The pair is named in the check; a world group names it too."""
    claims = [{"kind": "groups", "param": "k", "above": "q", "below": "p", "text": "q above p"},
              {"kind": "groups", "param": "k", "above": "p", "below": "q", "text": "p above q"}]
    spec = SweepSpec.model_validate({**SPEC.model_dump(), "claims": claims})
    q_over_p, p_over_q = sweep_claims(two_variants(), spec)
    assert not q_over_p.holds and q_over_p.checks[0].statistic == pytest.approx(4.5 / 10)
    assert q_over_p.checks[0].where == "q / p" and q_over_p.checks[0].means == pytest.approx({"q at k=0": 4.5 * 1.005,
                                                                                             "p": 10 * 1.005})
    assert not p_over_q.holds and p_over_q.checks[0].statistic == pytest.approx(5 / 9.5)
    # with a factor, as a `less` claim: q under 2 p at every k (q/p is at most 1.9) holds, under 1.8 p does not
    for factor, holds in ((2.0, True), (1.8, False)):
        (res,) = sweep_claims(two_variants(), spec.model_copy(update={"claims": [spec.claims[1].model_copy(
            update={"factor": factor})]}))
        assert res.holds is holds and res.checks[0].needs == f"> {1 / factor:.3g} at every value"
    alone = two_variants()[lambda d: d["sweep_variant"] == "p"].drop(columns="sweep_variant")
    assert sweep_claims(alone, spec) == []
    # about two variants, neither of them sweep.variant: still checked
    assert len(sweep_claims(two_variants(), spec.model_copy(update={"variant": "x"}))) == 2
    in_groups = two_variants().assign(gnss="dgnss")
    (res, _) = sweep_claims(in_groups, spec.model_copy(update={"groups": {"dgnss": {}}}))
    assert [c.where for c in res.checks] == ["q/dgnss / p/dgnss"]


def test_a_groups_claim_names_two_groups_or_two_variants():
    res = CliRunner().invoke(app, ["validate", str(ROOT / "configs" / "torben_fig3.yaml"), "--set",
                                   "sweep.claims.3.above=resetting"])
    assert res.exit_code == 2, res.output
    assert "sweep.claims.3: ['resetting', 'dgnss'] are neither two of the groups (dgnss, dualband) nor two variants" in res.output


def sweep(tmp_path, *args: str):
    return CliRunner().invoke(app, ["sweep", "--config", str(TABLE4), "--n", "2", "--horizon", "8", "--seeds", "2",
                                    "--out", str(tmp_path), "--quiet", *args])


def test_a_sweep_of_several_variants_runs_each_at_every_point_as_alone(tmp_path):
    res = sweep(tmp_path / "both", "noise", "--variants", "liu_eps0.1,proposed_d2.2", *NOISE)
    assert res.exit_code == 0, res.output
    (d,) = (tmp_path / "both").iterdir()
    assert d.name.startswith("bejarano_table4_sweep_noise_liu_eps0.1+proposed_d2.2_n2_8s_set-")
    m = pd.read_csv(d / "metrics.csv")
    runs = m.groupby(["sweep_variant", "param_value"])["seed"].nunique()
    assert runs.to_dict() == {(v, x): 2 for v in ("liu_eps0.1", "proposed_d2.2") for x in (0.0, 2.0)}
    assert json.loads((d / "manifest.json").read_text())["variants"] == ["liu_eps0.1", "proposed_d2.2"]
    table = (d / "table.md").read_text()
    assert row(table, "noise", "u", "proposed_d2.2 / liu_eps0.1")[3] != "–" and (d / "figures" / "sweep.png").exists()
    # its resolved config is the sweep that ran, a valid file: Table IV's delta_p1 is no setting of Liu's ESO
    resolved = yaml.safe_load((d / "config.resolved.yaml").read_text())
    assert list(resolved["sweep"]["params"]) == ["noise"] and resolved["sweep"]["variants"] == ["liu_eps0.1", "proposed_d2.2"]
    res = CliRunner().invoke(app, ["validate", str(d / "config.resolved.yaml")])
    assert res.exit_code == 0, res.output
    # a variant's runs are the same as in a sweep of it alone (runs do not depend on their batch)
    res = sweep(tmp_path / "alone", "noise", "--set", "sweep.variant=proposed_d2.2", *NOISE)
    assert res.exit_code == 0, res.output
    (alone,) = (tmp_path / "alone").iterdir()
    a = pd.read_csv(alone / "metrics.csv")
    b = m[m["sweep_variant"] == "proposed_d2.2"]
    key = ["param_value", "seed", "signal", "metric"]
    np.testing.assert_array_equal(a.sort_values(key)["value"], b.sort_values(key)["value"])
    # and compare pairs the two folders by variant and point: the sweep alone's points are its variant's (before: no
    # cell in common, exit 2), the other variant's are new
    res = CliRunner().invoke(app, ["compare", str(alone), str(d), "--metric", "std", "--format", "json"])
    assert res.exit_code == 0, res.output
    cells = pd.DataFrame(json.loads(res.output)["cells"])
    by_verdict = cells.groupby("verdict")["variant"].agg(set).to_dict()
    assert by_verdict == {"same": {"proposed_d2.2: noise=0", "proposed_d2.2: noise=2"},
                          "new": {"liu_eps0.1: noise=0", "liu_eps0.1: noise=2"}}
    # compare --variants pairs the two variants point by point and seed by seed
    res = CliRunner().invoke(app, ["compare", str(d), "--variants", "liu_eps0.1", "proposed_d2.2", "--metric", "std",
                                   "--format", "json"])
    cells = json.loads(res.output)["cells"]
    assert {c["variant"] for c in cells} == {"noise=0: proposed_d2.2 vs liu_eps0.1", "noise=2: proposed_d2.2 vs liu_eps0.1"}
    assert all(c["n"] == 2 for c in cells)


@pytest.mark.parametrize(("args", "expected"), [
    (["noise", "--variants", "liu_eps0.1,nope", *NOISE], "error: --variants: unknown variants ['nope'] (have: liu_eps0.2, "),
    (["noise", "--variants", "liu_eps0.1,liu_eps0.1", *NOISE], "error: --variants: ['liu_eps0.1'] given more than once"),
    (["noise", "--variants", "liu_eps0.1,", *NOISE], "error: --variants: comma-separated variant names, e.g. rise,srise, or "),
    (["noise", "--variants", "[liu_eps0.1]", *NOISE], "error: --variants: unknown variants ['[liu_eps0.1]']"),
    (["delta_p1", "--variants", "proposed_d1.2,liu_eps0.1"], "'delta_p1' is not a setting of variant 'liu_eps0.1'"),
])
def test_variants_that_cannot_be_swept_are_one_line_and_write_nothing(tmp_path, args, expected):
    res = sweep(tmp_path / "out", *args)
    assert res.exit_code == 2 and expected in res.output and len(res.output.strip().splitlines()) == 1, res.output
    assert not (tmp_path / "out").exists()


def test_validate_checks_the_configs_sweep_variants():
    res = CliRunner().invoke(app, ["validate", str(TABLE4), "--set", "sweep.variants=[proposed_d1.2, liu_eps0.1]"])
    assert res.exit_code == 2 and "'delta_p1' is not a setting of variant 'liu_eps0.1'" in res.output, res.output
    res = CliRunner().invoke(app, ["validate", str(TABLE4), "--set", "sweep.variants=[proposed_d1.2, proposed_d2.2]"])
    assert res.exit_code == 0, res.output
    res = CliRunner().invoke(app, ["validate", str(ROOT / "configs" / "tijjani_table3.yaml"), "--set", "sweep.scenario=S3",
                                   "--set", "sweep.variant=cdo_srise", "--set", "sweep.variants=[cdo_srise, rise]"])
    assert res.exit_code == 2 and "sweep.variants: 'rise' does not run on scenario 'S3'" in res.output, res.output


def test_all_sweeps_every_variant_of_the_sweeps_scenario(tmp_path):
    """Table III's sweep runs on S1, where rise, srise and cdo_srise run (cdo_srise alone also runs on S3)."""
    res = CliRunner().invoke(app, ["sweep", "--config", str(ROOT / "configs" / "tijjani_table3.yaml"), "yaw_noise",
                                   "--variants", "all", "--n", "2", "--horizon", "6", "--seeds", "1", "--out", str(tmp_path),
                                   "--quiet"])
    assert res.exit_code == 0, res.output
    (d,) = tmp_path.iterdir()
    assert d.name == "tijjani_table3_sweep_yaw_noise_rise+srise+cdo_srise_n2_6s"
    assert list(pd.read_csv(d / "metrics.csv")["sweep_variant"].unique()) == ["rise", "srise", "cdo_srise"]
