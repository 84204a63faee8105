"""The figures' data as a table: ``RunResult.trace_frame()`` and ``run --traces`` (``traces.csv.gz``)."""

import hashlib

import numpy as np
import pytest
from typer.testing import CliRunner

import marinebench as mb
from marinebench.cli import app
from marinebench.results.traces import COLUMNS, FILE, read_traces

from .conftest import ROOT


def test_the_frame_holds_every_traced_value_of_seed_0_of_each_variant(tiny_config):
    result = mb.run(mb.load(tiny_config))
    frame = result.trace_frame()
    t, truth, est = result.traces
    assert list(frame.columns) == COLUMNS
    assert set(frame["seed"]) == {0} and list(frame["variant"].unique()) == ["liu_eps0.2", "proposed_d1.2"]
    assert len(frame) == len(t) * len(result.traced) * len(truth)
    for col, run in enumerate(result.traced):
        variant = result.experiment.variants[result.run_variant[run]].name
        for signal in truth:
            rows = frame[(frame["variant"] == variant) & (frame["signal"] == signal)]
            np.testing.assert_array_equal(rows["t"], t)
            np.testing.assert_array_equal(rows["truth"], truth[signal][:, col])
            if signal in est:
                np.testing.assert_array_equal(rows["estimate"], est[signal][:, col])
            else:
                assert rows["estimate"].isna().all(), signal
    assert {"u", "sigma_u"} <= set(frame["signal"])


def test_a_result_without_traces_says_so(tiny_config):
    result = mb.run(mb.load(tiny_config), traces=False)
    with pytest.raises(ValueError, match="kept no traces"):
        result.trace_frame()


def test_writing_a_result_without_traces_is_refused_unless_its_config_draws_no_figures(tiny_config, tmp_path):
    """``marinebench.write`` of a ``run(..., traces=False)``: the figures cannot be drawn, so nothing is written (not
    a folder without them); a config without figures writes the rest."""
    with pytest.raises(ValueError, match="kept no traces, which its figures are drawn from"):
        mb.write(mb.run(mb.load(tiny_config), traces=False), tmp_path / "out")
    assert not (tmp_path / "out").exists()
    folder = mb.write(mb.run(mb.load(tiny_config, sets="figures=[]"), traces=False), tmp_path / "out")
    assert {p.name for p in folder.iterdir()} >= {"manifest.json", "metrics.csv", "table.md"}


def test_run_traces_writes_the_frame_gzipped_the_same_bytes_every_time(tiny_config, tmp_path):
    digests = []
    for out in ("a", "b"):
        res = CliRunner().invoke(app, ["run", str(tiny_config), "--traces", "--quiet", "--out", str(tmp_path / out)])
        assert res.exit_code == 0, res.output
        digests.append(hashlib.sha256((tmp_path / out / "tiny" / FILE).read_bytes()).hexdigest())
    assert digests[0] == digests[1]  # no time stamp or temporary file name in the gzip header
    written = read_traces(tmp_path / "a" / "tiny" / FILE)
    expected = mb.run(mb.load(tiny_config)).trace_frame()
    assert list(written.columns) == COLUMNS and len(written) == len(expected)
    assert (written[["scenario", "variant", "signal"]].to_numpy() == expected[["scenario", "variant", "signal"]].to_numpy()).all()
    np.testing.assert_allclose(written[["t", "truth"]], expected[["t", "truth"]], rtol=1e-9, atol=1e-300)
    assert "engine:" in (tmp_path / "a" / "tiny" / "config.resolved.yaml").read_text()
    assert "write_traces: true" in (tmp_path / "a" / "tiny" / "config.resolved.yaml").read_text()


def test_without_the_option_no_traces_are_written_and_resume_reruns_for_them(tiny_config, tmp_path):
    args = ["run", str(tiny_config), "--quiet", "--out", str(tmp_path)]
    assert CliRunner().invoke(app, args).exit_code == 0
    assert not (tmp_path / "tiny" / FILE).exists()
    res = CliRunner().invoke(app, [*args[:-3], "--out", str(tmp_path), "--resume", "--traces"])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "tiny" / FILE).exists()  # the traces are an input of the results: not "up to date"


def test_a_multi_scenario_experiment_names_each_world(tmp_path):
    config = ROOT / "configs" / "tijjani_table3.yaml"
    exp = mb.load(config, sets=["seeds=1", "scenarios.*.horizon=2"])
    frame = mb.run(exp).trace_frame()
    assert list(frame["scenario"].unique()) == list(exp.scenarios)
    assert frame.groupby("scenario")["t"].max().max() == pytest.approx(2.0, abs=0.05)
    # a controller's commands have a truth and no estimate
    assert frame.loc[frame["signal"] == "tau_depth", "estimate"].isna().all()


def _run_with_traces(config, out):
    res = CliRunner().invoke(app, ["run", str(config), "--traces", "--quiet", "--out", str(out)])
    assert res.exit_code == 0, res.output
    return out / config.stem


def test_figures_redraws_a_results_figures_from_its_traces_as_run_drew_them(tiny_config, tmp_path):
    import matplotlib.image as mpimg

    folder = _run_with_traces(tiny_config, tmp_path)
    drawn = {p.name: mpimg.imread(p) for p in (folder / "figures").iterdir()}
    for p in (folder / "figures").iterdir():
        p.unlink()
    res = CliRunner().invoke(app, ["figures", str(folder)])
    assert res.exit_code == 0 and res.output.strip() == f"{folder}: 2 figure(s) -> {folder / 'figures'}", res.output
    assert sorted(p.name for p in (folder / "figures").iterdir()) == sorted(drawn)
    for name, image in drawn.items():  # the traces are written to 10 digits: at most an anti-aliased pixel's shade
        assert np.abs(mpimg.imread(folder / "figures" / name) - image).max() <= 2 / 255, name


def test_figures_draws_what_the_edited_config_asks_for(tiny_config, tmp_path):
    import yaml

    folder = _run_with_traces(tiny_config, tmp_path)
    resolved = folder / "config.resolved.yaml"
    doc = yaml.safe_load(resolved.read_text())
    doc["figures"] = [{"file": "r_only_liu.png", "signals": ["r"], "variants": ["liu_eps0.2"]}]
    resolved.write_text(yaml.safe_dump(doc, sort_keys=False))
    assert CliRunner().invoke(app, ["figures", str(folder)]).exit_code == 0
    assert [p.name for p in (folder / "figures").iterdir()] == ["r_only_liu.png"]


def test_figures_of_a_study_draw_each_worlds_runs(tmp_path):
    config = ROOT / "configs" / "tijjani_table3.yaml"
    res = CliRunner().invoke(app, ["run", str(config), "--traces", "--quiet", "--out", str(tmp_path),
                                   "--set", "seeds=1", "--set", "scenarios.*.horizon=2"])
    assert res.exit_code == 0, res.output
    folder = tmp_path / config.stem
    before = sorted(p.name for p in (folder / "figures").iterdir())
    assert CliRunner().invoke(app, ["figures", str(folder)]).exit_code == 0
    assert sorted(p.name for p in (folder / "figures").iterdir()) == before and before


def test_figures_without_traces_or_with_a_variant_the_config_lost_is_one_line(tiny_config, tmp_path):
    import yaml

    plain = tmp_path / "plain"
    assert CliRunner().invoke(app, ["run", str(tiny_config), "--quiet", "--out", str(plain)]).exit_code == 0
    res = CliRunner().invoke(app, ["figures", str(plain / "tiny")])
    assert res.exit_code == 2 and res.output.strip() == f"error: {plain / 'tiny'}: no {FILE} to draw from (run the config with --traces)"
    folder = _run_with_traces(tiny_config, tmp_path / "traced")
    doc = yaml.safe_load((folder / "config.resolved.yaml").read_text())
    doc["variants"] = doc["variants"][:1]
    doc["table"]["paper"]["values"] = {}
    (folder / "config.resolved.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    before = {p.name: p.read_bytes() for p in (folder / "figures").iterdir()}
    res = CliRunner().invoke(app, ["figures", str(folder)])
    assert res.exit_code == 2 and "variants ['proposed_d1.2'] are not in the config (have: liu_eps0.2)" in res.output, res.output
    assert {p.name: p.read_bytes() for p in (folder / "figures").iterdir()} == before  # nothing half-drawn
    res = CliRunner().invoke(app, ["figures", str(tmp_path / "nope")])
    assert res.exit_code == 2 and res.output.strip() == f"error: {tmp_path / 'nope'}: no such directory"
    # a tree of results (before: "no traces.csv.gz to draw from", as if it were one): what in it can be drawn
    res = CliRunner().invoke(app, ["figures", str(plain)])
    assert res.exit_code == 2 and res.output.strip() == (
        f"error: {plain}: not a result folder but a tree of them: name the ones to redraw (none of its 1 can be: only "
        "sweeps and runs with --traces)")
    res = CliRunner().invoke(app, ["figures", str(tmp_path / "traced")])
    assert res.exit_code == 2
    assert res.output.strip().endswith(f"(1 of its 1 can be, sweeps and runs with --traces, e.g. {folder})")


@pytest.mark.parametrize("kind", ["file", "link"])
def test_figures_leaves_a_file_or_link_named_figures_where_the_figures_go(kind, tiny_config, tmp_path):
    """A result's figures/ is swapped whole for the new drawings; a file or a symbolic link of that name is not the
    result's (someone put it there): before, it was swapped out and deleted, rc 0."""
    import shutil

    folder = _run_with_traces(tiny_config, tmp_path)
    shutil.rmtree(folder / "figures")
    if kind == "file":
        (folder / "figures").write_text("notes")
    else:
        (tmp_path / "mine").mkdir()
        (tmp_path / "mine" / "plot.png").write_text("png")
        (folder / "figures").symlink_to(tmp_path / "mine")
    res = CliRunner().invoke(app, ["figures", str(folder)])
    what = "a file" if kind == "file" else "a symbolic link"
    assert res.exit_code == 2 and res.output.strip() == (f"error: {folder / 'figures'}: {what}, not the result's "
                                                         "figures folder: not replaced (move it)"), res.output
    if kind == "file":
        assert (folder / "figures").read_text() == "notes"
    else:
        assert (folder / "figures").is_symlink() and (tmp_path / "mine" / "plot.png").read_text() == "png"


@pytest.mark.parametrize(("edit", "expected"), [
    ({"signals": ["sigma_r", "nosuch"]}, "no trace of ['nosuch']"),
    ({"signals": ["r"], "variants": ["added"]}, "no seed-0 run of variants ['added']"),
    ({"kind": "tracking", "signals": ["r"]}, "no trace of ['r_ref', 'tau_r']"),
])
def test_figures_of_a_signal_or_variant_the_traces_lack_is_one_line(tiny_config, tmp_path, edit, expected):
    """An edited figure that asks for a signal never traced, a tracking layout on an observer run (no control
    input to draw), or a variant added to the config after the run. Before, a traceback (KeyError,
    IndexError); now one line naming the figure, and the figures drawn before stay as they were."""
    import yaml

    folder = _run_with_traces(tiny_config, tmp_path)
    doc = yaml.safe_load((folder / "config.resolved.yaml").read_text())
    doc["variants"].append({**doc["variants"][0], "name": "added"})
    doc["figures"] = [{"file": "edited.png", **edit}]
    (folder / "config.resolved.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    before = {p.name: p.read_bytes() for p in (folder / "figures").iterdir()}
    res = CliRunner().invoke(app, ["figures", str(folder)])
    assert res.exit_code == 2 and len(res.output.strip().splitlines()) == 1, res.output
    assert res.output.startswith(f"error: {folder / 'config.resolved.yaml'}: figures: edited.png: {expected} in {FILE} "
                                 "(it holds signals "), res.output
    assert {p.name: p.read_bytes() for p in (folder / "figures").iterdir()} == before


def test_a_damaged_traces_file_is_one_line_naming_it(tiny_config, tmp_path):
    """Before, each of these was a traceback from gzip or pandas (BadGzipFile, EmptyDataError, KeyError), and a
    gzip cut short printed only 'Aborted!' (its EOFError read as Ctrl-D by the command line), exit code 1."""
    import gzip

    folder = _run_with_traces(tiny_config, tmp_path)
    good = gzip.decompress((folder / FILE).read_bytes()).decode()
    header, first = good.splitlines()[:2]
    cases = {
        (folder / FILE).read_bytes()[:300]: "not a readable CSV (Compressed file ended before the end-of-stream marker",
        b"plain text": "not a readable CSV (Not a gzipped file",
        gzip.compress(b""): "not a readable CSV (No columns to parse from file)",
        gzip.compress(f"{header}\n".encode()): "no rows",
        gzip.compress(b"scenario,variant,seed,signal,truth,estimate\ns,a,0,u,1,1\n"): "missing column(s) ['t']; is this a "
                                                                                   "marinebench traces.csv.gz?",
        gzip.compress(f"{header}\n{first}\n{first.replace(',0,', ',x,', 1)}\n".encode()): "column 'seed' is not numeric",
        gzip.compress(good[: len(good) // 2].encode()): ": a row without its scenario, variant, seed, t, signal",
        # cut at a line's end: every row whole, the last runs' signals missing (before: KeyError)
        gzip.compress(good[: good.index("\n", len(good) // 2) + 1].encode()): "' for variant proposed_d1.2, seed 0 (a "
                                                                              "truncated file?)",
    }
    for content, expected in cases.items():
        (folder / FILE).write_bytes(content)
        res = CliRunner().invoke(app, ["figures", str(folder)])
        lines = res.output.strip().splitlines()
        assert res.exit_code == 2 and len(lines) == 1, res.output
        assert lines[0].startswith(f"error: {folder / FILE}: ") and expected in lines[0], lines[0]


@pytest.fixture(scope="module")
def small_sweeps(tmp_path_factory):
    """A one-at-a-time sweep (two groups, a dotted line at the variant's own value) and a grid sweep of Torben's
    Fig. 3 config, a few short runs each."""
    out = tmp_path_factory.mktemp("sweeps")
    config = str(ROOT / "configs" / "torben_fig3.yaml")
    for args in (["k", "eps", "--n", "3"], ["k", "delta", "--grid", "--n", "2", "--gnss", "dgnss"]):
        res = CliRunner().invoke(app, ["sweep", *args, "--config", config, "--horizon", "40", "--out", str(out), "--quiet"])
        assert res.exit_code == 0, res.output
    return {"sweep.png": out / "torben_fig3_sweep_k_eps_n3_40s", "grid.png": out / "torben_fig3_sweep_grid_k_delta_dgnss_n2_40s"}


@pytest.mark.parametrize("file", ["sweep.png", "grid.png"])
def test_figures_redraws_a_sweeps_figure_from_its_metrics_as_the_sweep_drew_it(small_sweeps, file, tmp_path):
    """A sweep keeps no traces: its figure is drawn from metrics.csv, which holds every value it shows. Before, the
    command refused every sweep folder ('no traces.csv.gz ... run the config with --traces', which sweep has not)."""
    import shutil

    folder = tmp_path / small_sweeps[file].name
    shutil.copytree(small_sweeps[file], folder)
    drawn = (folder / "figures" / file).read_bytes()
    shutil.rmtree(folder / "figures")
    res = CliRunner().invoke(app, ["figures", str(folder)])
    assert res.exit_code == 0 and res.output.strip() == f"{folder}: 1 figure(s) -> {folder / 'figures'}", res.output
    assert [p.name for p in (folder / "figures").iterdir()] == [file]
    assert (folder / "figures" / file).read_bytes() == drawn  # the same values, drawn the same way


def test_figures_of_a_sweep_draws_what_its_edited_sweep_section_asks_for(small_sweeps, tmp_path):
    import shutil

    import yaml

    folder = tmp_path / "swept"
    shutil.copytree(small_sweeps["sweep.png"], folder)
    drawn = (folder / "figures" / "sweep.png").read_bytes()
    resolved = folder / "config.resolved.yaml"
    doc = yaml.safe_load(resolved.read_text())
    doc["sweep"]["params"]["k"]["label"] = "the gain k, relabelled"
    resolved.write_text(yaml.safe_dump(doc, sort_keys=False))
    assert CliRunner().invoke(app, ["figures", str(folder)]).exit_code == 0
    relabelled = (folder / "figures" / "sweep.png").read_bytes()
    assert relabelled != drawn
    for edit, expected in [({"signals": ["nope"]}, "no signal(s) ['nope'] of metric J_tot in"),
                           ({"metric": "J_tot_steady", "metrics": None}, None)]:
        doc["sweep"] |= edit
        resolved.write_text(yaml.safe_dump(doc, sort_keys=False))
        res = CliRunner().invoke(app, ["figures", str(folder)])
        if expected is None:  # another metric of the file
            assert res.exit_code == 0 and (folder / "figures" / "sweep.png").read_bytes() != relabelled, res.output
            continue
        assert res.exit_code == 2 and len(res.output.strip().splitlines()) == 1, res.output
        assert res.output.startswith(f"error: {resolved}: sweep: {expected} {folder / 'metrics.csv'} (its signals there: z)")
        assert (folder / "figures" / "sweep.png").read_bytes() == relabelled  # nothing half-drawn
        doc["sweep"].pop("signals")
    doc["sweep"]["params"].pop("eps")  # and the claims about it, or the config would not validate
    doc["sweep"]["claims"] = [claim for claim in doc["sweep"]["claims"] if claim["param"] != "eps"]
    resolved.write_text(yaml.safe_dump(doc, sort_keys=False))
    res = CliRunner().invoke(app, ["figures", str(folder)])  # before: a KeyError traceback, exit 1
    assert res.exit_code == 2 and res.output.strip() == (f"error: {resolved}: sweep.params: no ['eps'], which "
                                                         f"{folder / 'metrics.csv'} holds (have: k)"), res.output


def test_figures_of_a_sweep_without_its_columns_is_one_line(small_sweeps, tmp_path):
    import shutil

    import pandas as pd

    folder = tmp_path / "grid"
    shutil.copytree(small_sweeps["grid.png"], folder)
    pd.read_csv(folder / "metrics.csv").drop(columns="param2_value").to_csv(folder / "metrics.csv", index=False)
    res = CliRunner().invoke(app, ["figures", str(folder)])
    assert res.exit_code == 2 and res.output.strip() == (f"error: {folder / 'metrics.csv'}: missing column(s) "
                                                         "['param2_value']; is this a grid sweep's metrics.csv?"), res.output
