"""Sweep parameters given in place on the command line (``KEY=LO..HI[:log]``), on any config, with or without a
``sweep`` section."""

import json

import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

from marinebench.cli import app
from marinebench.errors import ConfigError
from marinebench.experiments.sweep import inline_params

runner = CliRunner()


def test_names_pass_through_and_a_parameter_in_place_becomes_its_setting():
    names, sets = inline_params(["k", "world.gnss_sigma=0.05..3:log", "delta_p1=-1..2.5"])
    assert names == ["k", "gnss_sigma", "delta_p1"]
    arg, value = sets["sweep.params.gnss_sigma"]
    assert arg == "world.gnss_sigma=0.05..3:log"
    assert json.loads(value) == {"key": "world.gnss_sigma", "range": [0.05, 3.0], "spacing": "log"}
    assert json.loads(sets["sweep.params.delta_p1"][1])["range"] == [-1.0, 2.5]


@pytest.mark.parametrize("arg", ["eps=0.1-1", "eps=..1", "eps=0.1..1:cubic", "=0.1..1", "a b=0.1..1", "eps=x..1"])
def test_a_malformed_parameter_is_refused_naming_it(arg):
    with pytest.raises(ConfigError, match=r"expected a name of sweep.params or KEY=LO..HI\[:log\]") as info:
        inline_params([arg])
    assert info.value.file == "PARAM" and info.value.key == arg


def test_the_same_name_twice_is_refused():
    with pytest.raises(ConfigError, match="'eps' is swept twice"):
        inline_params(["eps=0.1..1", "observer.eps=0.2..2"])


def test_a_config_without_a_sweep_section_sweeps_a_parameter_given_in_place(tiny_config, tmp_path):
    res = runner.invoke(app, ["sweep", "--config", str(tiny_config), "eps=0.1..0.4", "--n", "3", "--out", str(tmp_path),
                              "--quiet"])
    assert res.exit_code == 0, res.output
    folder = tmp_path / "tiny_sweep_n3_eps=0.1..0.4_2seeds"
    metrics = pd.read_csv(folder / "metrics.csv")
    assert sorted(set(metrics["param_value"])) == pytest.approx([0.1, 0.25, 0.4])
    assert set(metrics["experiment"]) == {folder.name} and set(metrics["metric"]) == {"std"}
    spec = yaml.safe_load((folder / "config.resolved.yaml").read_text())["sweep"]
    # the defaults are written out: the experiment's first variant and first metric
    assert spec["variant"] == "liu_eps0.2" and spec["metric"] == "std"
    assert spec["params"]["eps"]["key"] == "eps" and spec["params"]["eps"]["range"] == [0.1, 0.4]
    # the resolved config is a config in its own right: the same sweep by name, the same numbers
    res = runner.invoke(app, ["sweep", "--config", str(folder / "config.resolved.yaml"), "eps", "--n", "3", "--out",
                              str(tmp_path / "again"), "--quiet"])
    assert res.exit_code == 0, res.output
    again = pd.read_csv(tmp_path / "again" / "tiny_sweep_n3_2seeds" / "metrics.csv")
    pd.testing.assert_series_equal(again["value"], metrics["value"])


@pytest.mark.parametrize(("arg", "expected"), [
    ("eps=0.4..0.1", "error: eps=0.4..0.1: bad range (0.4, 0.1) for linear spacing"),
    ("eps=0..1:log", "error: eps=0..1:log: bad range (0.0, 1.0) for log spacing"),
    # equal ends: before, n runs at one value, then a traceback (pandas' pivot) after simulating them
    ("eps=0.2..0.2", "error: eps=0.2..0.2: bad range (0.2, 0.2) for linear spacing (from a lower to a higher value)"),
    ("nosuch=0.1..1", "error: nosuch=0.1..1: 'nosuch' is not a setting of variant 'liu_eps0.2'"),
])
def test_an_error_in_a_parameter_given_in_place_names_the_argument(tiny_config, tmp_path, arg, expected):
    res = runner.invoke(app, ["sweep", "--config", str(tiny_config), arg, "--n", "2", "--out", str(tmp_path / "out")])
    assert res.exit_code == 2 and res.output.startswith(expected) and len(res.output.strip().splitlines()) == 1, res.output
    assert not (tmp_path / "out").exists()


def test_a_config_without_a_sweep_section_and_no_parameter_in_place_says_how(tiny_config, tmp_path):
    res = runner.invoke(app, ["sweep", "--config", str(tiny_config), "eps", "--out", str(tmp_path)])
    assert res.exit_code == 2 and "give the parameters in place, KEY=LO..HI[:log]" in res.output, res.output


def test_an_error_about_a_grid_point_names_the_parameters_given_in_place(tiny_config, tmp_path):
    """A world without position noise has none to scale: the check of each point names the pair swept."""
    res = runner.invoke(app, ["sweep", "--config", str(tiny_config), "eps=0.1..0.4", "world.position_noise_scale=0..1",
                              "--grid", "--n", "2", "--out", str(tmp_path), "--set", "scenario.sensors.position_noise={kind: none}"])
    assert res.exit_code == 2 and res.output.startswith("error: eps=0.1..0.4 world.position_noise_scale=0..1: eps=0.1, "
                                                        "position_noise_scale=0: scenario "), res.output


def test_without_a_parameter_named_every_one_of_the_section_is_swept(tiny_config, tmp_path):
    section = "sweep={params: {eps: {key: eps, range: [0.1, 0.4]}, noise: {key: world.position_noise_scale, range: [0, 1]}}}"
    res = runner.invoke(app, ["sweep", "--config", str(tiny_config), "--n", "2", "--set", section, "--out",
                              str(tmp_path / "one"), "--quiet"])
    assert res.exit_code == 0, res.output
    (folder,) = (tmp_path / "one").iterdir()
    assert set(pd.read_csv(folder / "metrics.csv")["param"]) == {"eps", "noise"}
    # a section of exactly two parameters is a grid's pair
    res = runner.invoke(app, ["sweep", "--config", str(tiny_config), "--grid", "--n", "2", "--set", section, "--out",
                              str(tmp_path / "grid"), "--quiet"])
    assert res.exit_code == 0, res.output
    (folder,) = (tmp_path / "grid").iterdir()
    metrics = pd.read_csv(folder / "metrics.csv")
    assert set(metrics["param"]) == {"eps"} and set(metrics["param2"]) == {"noise"} and len(set(metrics["variant"])) == 4


def test_all_variants_of_a_config_without_a_sweep_section_is_one_line(tiny_config, tmp_path):
    """Before, `--variants all` on such a config crashed with a traceback (AttributeError)."""
    res = runner.invoke(app, ["sweep", "--config", str(tiny_config), "eps", "--variants", "all", "--out", str(tmp_path)])
    assert res.exit_code == 2 and len(res.output.strip().splitlines()) == 1, res.output
    assert "this config has no 'sweep' section: give the parameters in place" in res.output
    res = runner.invoke(app, ["sweep", "--config", str(tiny_config), "world.position_noise_scale=0..1", "--variants", "all",
                              "--n", "2", "--out", str(tmp_path / "all"), "--quiet"])
    assert res.exit_code == 0, res.output
    (folder,) = (tmp_path / "all").iterdir()
    assert set(pd.read_csv(folder / "metrics.csv")["sweep_variant"]) == {"liu_eps0.2", "proposed_d1.2"}


def test_a_parameter_given_in_place_over_one_of_the_section_names_the_folder_once(tiny_config):
    """Its argument names the folder (as --set does); before, the section's name of it came first as well
    (``_sweep_eps_eps=0.2..0.3``). A parameter named, not given in place, keeps its tag."""
    from marinebench.experiments.sweep import sweep_suffix
    from marinebench.loading import load_experiment

    section = "sweep={params: {eps: {key: eps, range: [0.1, 0.4]}, noise: {key: world.position_noise_scale, range: [0, 1]}}}"
    exp, _ = load_experiment(tiny_config, [section])
    assert sweep_suffix(exp, ["eps"], overrides=["eps=0.2..0.3"]) == "_sweep_eps=0.2..0.3_2seeds"
    assert sweep_suffix(exp, ["eps"], overrides=["seed=3"]) == "_sweep_eps_seed=3_2seeds"
    assert sweep_suffix(exp, ["eps"], overrides=["world.position_noise_scale=0..2"]) == "_sweep_eps_world.position_noise_scale=0..2_2seeds"


CLAIMS = ("sweep={params: {eps: {key: eps, range: [0.1, 0.4]}}, claims: ["
          "{kind: probe, param: eps, at: 0.1, vs: 0.4, factor: 10, text: at both ends}, "
          "{kind: trend, param: eps, range: [0.2, 0.3], text: inside}, "
          "{kind: trend, param: eps, range: [0.1, 0.2], text: a low trend}]}")


def test_claims_outside_the_range_given_in_place_are_left_out_with_a_note(tiny_config, tmp_path):
    """Narrowing a parameter of the section in place (zooming in) leaves its claims at values outside the new range
    unchecked, each with a note; before, the sweep was refused (the claim's values outside the range)."""
    res = runner.invoke(app, ["sweep", "--config", str(tiny_config), "eps=0.15..0.35", "--n", "3", "--set", CLAIMS,
                              "--out", str(tmp_path / "out")])
    assert res.exit_code == 0, res.output
    notes = [line for line in res.output.splitlines() if line.startswith("note:")]
    assert notes == [f"note: {tiny_config}: sweep.claims.0 is not checked ('at both ends'): 0.1, 0.4 outside eps=0.15..0.35",
                     f"note: {tiny_config}: sweep.claims.2 is not checked ('a low trend'): 0.1 outside eps=0.15..0.35"]
    (folder,) = (tmp_path / "out").iterdir()
    spec = yaml.safe_load((folder / "config.resolved.yaml").read_text())["sweep"]
    assert [c["text"] for c in spec["claims"]] == ["inside"]
    assert "| inside |" in (folder / "claims.md").read_text()


def test_claims_beyond_keeps_claims_inside_and_about_other_parameters():
    from marinebench.experiments.sweep import claims_beyond

    _, inline = inline_params(["k=0.5..1"])
    claims = [{"kind": "probe", "param": "k", "at": 0.7, "vs": 0.0, "text": "a"},
              {"kind": "probe", "param": "k", "at": 0.7, "vs": 0.9, "text": "b"},
              {"kind": "trend", "param": "delta", "range": [2.5, 10.0], "text": "c"},
              {"kind": "groups", "param": "k", "above": "x", "below": "y", "text": "d"}]
    kept, notes = claims_beyond(claims, inline)
    assert [c["text"] for c in kept] == ["b", "c", "d"]
    assert notes == ["sweep.claims.0 is not checked ('a'): 0 outside k=0.5..1"]
    assert claims_beyond(claims, {}) == (claims, [])
