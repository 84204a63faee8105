import json
import re
import shlex

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from marinebench.environment.signals import Constant, RandomSinusoid
from marinebench.errors import ConfigError
from marinebench.loading import apply_set
from marinebench.metrics.stats import mean_ci, spearman_rows
from marinebench.results import writer
from marinebench.results.writer import atomic_directory, atomic_write_text
from marinebench.scenario import stream_rngs
from marinebench.sensors.noise import BandLimitedUniform
from marinebench.sim.recorders import ErrorMoments, Traces


def sample_noise(spec, seed=0, T=200.0, dt=0.05):
    batch = spec.sample(stream_rngs(seed, [0], "noise"), 2)
    t = np.arange(0, T, dt)
    return t, np.array([batch(tk)[0] for tk in t])  # (T, 2)


def test_noise_is_bounded_and_band_limited():
    spec = BandLimitedUniform(bound=0.2, rms=0.15)  # heavy saturation still stays bounded
    _, n = sample_noise(spec)
    assert np.abs(n).max() <= 0.2 + 1e-12
    spec = BandLimitedUniform(bound=10.0, rms=0.033)  # no saturation: energy only in 0.1-0.5 Hz
    t, n = sample_noise(spec, T=400.0)
    f = np.fft.rfftfreq(len(t), 0.05)
    P = np.abs(np.fft.rfft(n[:, 0])) ** 2
    inband = (f >= 0.09) & (f <= 0.51)
    assert P[inband].sum() / P.sum() > 0.97
    assert abs(n.std() / 0.033 - 1) < 0.15


def test_noise_defaults_to_the_std_of_a_uniform_and_needs_a_band():
    """Without rms the std is that of U(-bound, bound); a flat response passes it unchanged (the trapezoid mean of
    a constant is the constant); a band of zero width is refused."""
    spec = BandLimitedUniform(bound=0.3)
    assert spec.std == pytest.approx(0.3 / np.sqrt(3.0), rel=1e-15)
    flat = spec.response_std(lambda w: np.ones((2, w.size)))
    np.testing.assert_allclose(flat, [spec.std, spec.std], rtol=1e-12)
    with pytest.raises(ValueError, match="f_low=0.3 must be below f_high=0.3"):
        BandLimitedUniform(f_low=0.3, f_high=0.3)


def test_noise_reproducible_and_channels_independent():
    spec = BandLimitedUniform()
    _, a = sample_noise(spec, seed=3)
    _, b = sample_noise(spec, seed=3)
    _, c = sample_noise(spec, seed=4)
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)
    assert abs(np.corrcoef(a.T)[0, 1]) < 0.3


def test_random_sinusoid_draws_its_parameters_in_their_ranges_per_seed():
    """Bejarano's excitation s(t) = b + a sin(2 pi f t + phi): one draw of b, a, f (uniform in their ranges) and
    phi (uniform in [0, 2 pi)) per seed, the same draws for a seed in any batch; take() keeps the chosen runs."""
    spec = RandomSinusoid(bias=(1.0, 2.0), amplitude=(0.5, 0.75), frequency=(0.02, 0.05))
    seeds = list(range(400))
    batch = spec.sample(stream_rngs(3, seeds, "F_u"))
    assert 1.0 <= batch.bias.min() < 1.05 and 1.95 < batch.bias.max() <= 2.0
    assert 0.5 <= batch.amplitude.min() < 0.51 and 0.74 < batch.amplitude.max() <= 0.75
    f = batch.omega / (2 * np.pi)
    assert 0.02 <= f.min() < 0.021 and 0.049 < f.max() <= 0.05
    assert 0.0 <= batch.phase.min() < 0.1 and 6.2 < batch.phase.max() < 2 * np.pi
    t = 7.3
    np.testing.assert_allclose(batch(t), batch.bias + batch.amplitude * np.sin(2 * np.pi * f * t + batch.phase),
                               rtol=1e-14)
    one = spec.sample(stream_rngs(3, [5], "F_u"))
    assert one(t)[0] == batch(t)[5]
    picked = batch.take(np.array([5, 5, 0]))
    np.testing.assert_allclose(picked(t), batch(t)[[5, 5, 0]], rtol=1e-14)
    const = Constant(value=-0.4).sample(stream_rngs(3, [0, 1], "F_u"))
    assert const(0.0).tolist() == const(12.5).tolist() == [-0.4, -0.4]


@pytest.mark.parametrize(("fields", "message"), [
    ({"bias": (1.0, 0.5)}, "bias: lower bound 1.0 exceeds upper bound 0.5"),
    ({"frequency": (0.2, 0.1)}, "frequency: lower bound 0.2 exceeds upper bound 0.1"),
    ({"amplitude": (-0.1, 0.1)}, "amplitude and frequency ranges must be non-negative"),
    ({"frequency": (-0.1, 0.1)}, "amplitude and frequency ranges must be non-negative"),
])
def test_random_sinusoid_refuses_reversed_or_negative_ranges(fields, message):
    with pytest.raises(ValueError, match=message):
        RandomSinusoid(**fields)
    RandomSinusoid(bias=(-1.0, -1.0), amplitude=(0.0, 0.0), frequency=(0.0, 0.0))  # a point range, bias below 0: fine


def test_error_moments_match_numpy():
    rng = np.random.default_rng(0)
    e = rng.normal(1.0, 0.5, size=(500, 3))
    rec = ErrorMoments(["u"], t_start=1.0, t_end=3.0)
    for k in range(500):
        rec.update(k, k * 0.01, {"u": np.zeros(3)}, {"u": e[k]})
    window = e[100:301]
    np.testing.assert_allclose(rec.result("std")["u"], window.std(axis=0), rtol=1e-12)
    np.testing.assert_allclose(rec.result("rmse")["u"], np.sqrt((window**2).mean(axis=0)), rtol=1e-12)
    np.testing.assert_allclose(rec.result("max_abs")["u"], np.abs(window).max(axis=0))


def test_traces_keep_every_nth_step_of_the_chosen_runs():
    every, third = Traces(["u"], 1), Traces(["u"], 3, np.array([1]))
    for k in range(7):
        for tr in (every, third):
            tr.update(k, 0.1 * k, {"u": np.array([k, 10.0 * k])}, {"u": np.array([-k, -10.0 * k])})
    t, truth, est = every.arrays()
    assert t.size == 7 and truth["u"].shape == (7, 2)
    t, truth, est = third.arrays()
    np.testing.assert_allclose(t, [0.0, 0.3, 0.6])
    assert truth["u"][:, 0].tolist() == [0.0, 30.0, 60.0] and est["u"][:, 0].tolist() == [0.0, -30.0, -60.0]


def test_error_moments_of_one_sample_and_of_none():
    """A window that holds one step gives that step's error (std 0); an empty one is an error naming the window."""
    one = ErrorMoments(["u"], t_start=0.5, t_end=0.5)
    for k in range(3):
        one.update(k, k * 0.5, {"u": np.zeros(2)}, {"u": np.array([-0.3, 0.4]) * (k + 1)})
    assert one.result("std")["u"].tolist() == [0.0, 0.0]
    np.testing.assert_allclose(one.result("rmse")["u"], [0.6, 0.8])
    np.testing.assert_allclose(one.result("mean")["u"], [-0.6, 0.8])
    none = ErrorMoments(["u"], t_start=5.0, t_end=6.0)
    none.update(0, 0.0, {"u": np.zeros(2)}, {"u": np.ones(2)})
    with pytest.raises(ValueError, match=r"no samples in the metric window t in \[5.0, 6.0\]"):
        none.result("rmse")


@settings(max_examples=30)
@given(st.lists(st.floats(-1e3, 1e3), min_size=2, max_size=40))
def test_mean_ci_contains_mean(values):
    m, lo, hi = mean_ci(np.array(values))
    assert lo <= m + 1e-9 and m <= hi + 1e-9


def test_mean_ci_coverage():
    rng = np.random.default_rng(1)
    hits = sum(lo <= 2.0 <= hi for lo, hi in (mean_ci(rng.normal(2.0, 1.0, 5))[1:] for _ in range(2000)))
    assert 0.93 < hits / 2000 < 0.97


def test_mean_ci_ignores_nan_and_single_value():
    m, lo, hi = mean_ci(np.array([1.0, np.nan]))
    assert m == 1.0 and np.isnan(lo) and np.isnan(hi)


def test_spearman_rows_is_scipys_spearmanr_row_by_row():
    """A trend claim's ρ and its bootstrap (experiments/curves.py): each row as scipy.stats.spearmanr gives it, with
    ties (average ranks), and nan for a row holding a nan or constant (scipy warns and gives nan)."""
    import warnings

    from scipy.stats import spearmanr

    rng = np.random.default_rng(4)
    x = np.array([0.1, 0.3, 1.0, 2.0, 5.0, 10.0])
    ys = np.vstack([rng.normal(size=(40, 6)), np.round(rng.normal(size=(20, 6))), x[::-1], x ** 2, np.full(6, 3.0),
                    [1, 2, np.nan, 4, 5, 6]])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        expected = np.array([spearmanr(x, y).statistic for y in ys])
    ours = spearman_rows(x, ys)
    np.testing.assert_allclose(ours, expected, rtol=1e-12, atol=1e-15)
    assert np.isnan(ours[-2:]).all() and ours[-4] == -1.0 and ours[-3] == 1.0
    assert np.isfinite(ours[:-2]).all()


def test_atomic_directory_keeps_old_results_on_failure(tmp_path):
    target = tmp_path / "exp"
    with atomic_directory(target) as d:
        (d / "manifest.json").write_text("old")
        (d / "metrics.csv").write_text("")
    with pytest.raises(RuntimeError), atomic_directory(target) as d:
        (d / "manifest.json").write_text("half")
        (d / "metrics.csv").write_text("")
        raise RuntimeError("interrupted")
    assert (target / "manifest.json").read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["exp"]


def test_atomic_directory_swaps_in_one_step_on_linux(tmp_path, monkeypatch):
    """The previous results are exchanged with the new ones by one renameat2 (Linux, where marinebench's CI
    runs): os.replace, which would leave a moment without the folder, is not called."""
    target = tmp_path / "exp"
    with atomic_directory(target) as d:
        (d / "manifest.json").write_text("old")
        (d / "metrics.csv").write_text("")
    monkeypatch.setattr(writer.os, "replace", lambda *a: pytest.fail("two-step rename used"))
    with atomic_directory(target) as d:
        (d / "manifest.json").write_text("new")
        (d / "metrics.csv").write_text("")
    assert (target / "manifest.json").read_text() == "new"
    assert [p.name for p in tmp_path.iterdir()] == ["exp"]


def test_atomic_directory_falls_back_to_two_renames(tmp_path, monkeypatch):
    """Where no exchange exists (another OS, an old C library, a file system without it), the same result."""
    monkeypatch.setattr(writer, "_exchange", lambda a, b: False)
    target = tmp_path / "exp"
    for text in ("old", "new"):
        with atomic_directory(target) as d:
            (d / "manifest.json").write_text(text)
            (d / "metrics.csv").write_text("")
    assert (target / "manifest.json").read_text() == "new"
    assert [p.name for p in tmp_path.iterdir()] == ["exp"]


def test_a_killed_writers_temporary_folders_are_removed_by_the_next_write(tmp_path):
    """SIGKILL (or a power cut) during a write leaves .exp.tmp-<host>-<pid>-* behind; the next write of the same
    folder removes it when that process is gone, and leaves a live process's and another host's alone."""
    import subprocess
    import sys

    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True,
                          check=True).stdout.strip()
    owner = writer._owner()
    host = owner.rsplit("-", 1)[0]
    orphans = [f".exp.tmp-{host}-{dead}-abc", f".exp.old-{host}-{dead}-abc"]
    kept = [f".exp.tmp-{owner}-live", f".exp.tmp-otherhost-{dead}-abc", f".other.tmp-{host}-{dead}-x"]
    for name in orphans + kept:
        (tmp_path / name).mkdir()
        (tmp_path / name / "manifest.json").write_text("half")
    with atomic_directory(tmp_path / "exp") as d:
        assert d.name.startswith(f".exp.tmp-{owner}-")
        (d / "manifest.json").write_text("new")
        (d / "metrics.csv").write_text("")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["exp", *kept])


def test_atomic_outputs_get_the_modes_the_umask_gives(tmp_path):
    """Not the 0700/0600 of mkdtemp/mkstemp: results on a shared machine are readable as any file would be."""
    import os

    old = os.umask(0o022)
    try:
        with atomic_directory(tmp_path / "exp") as d:
            atomic_write_text(d / "table.md", "x")
    finally:
        os.umask(old)
    assert (tmp_path / "exp").stat().st_mode & 0o777 == 0o755
    assert (tmp_path / "exp" / "table.md").stat().st_mode & 0o777 == 0o644


def test_a_failed_single_file_write_keeps_the_previous_file_and_leaves_no_temporary(tmp_path):
    """atomic_write_text: text that cannot be encoded (or a full disk, a kill) fails the write, not the file."""
    target = tmp_path / "table.md"
    atomic_write_text(target, "old")
    with pytest.raises(UnicodeEncodeError):
        atomic_write_text(target, "\udc80")  # a lone surrogate: no UTF-8 for it
    assert [p.name for p in tmp_path.iterdir()] == ["table.md"] and target.read_text() == "old"
    atomic_write_text(target, "new")
    assert [p.name for p in tmp_path.iterdir()] == ["table.md"] and target.read_text() == "new"


def test_apply_set_paths():
    doc = {"seeds": 1, "variants": [{"name": "a.b", "observer": {"eps": 1}}], "scenario": {"dt": 1}}
    assert apply_set(doc, "variants[a.b].observer.eps=0.5") == ["variants.0.observer.eps"]  # the key set, by index
    apply_set(doc, "variants.0.name=c")
    apply_set(doc, "scenario.sensors.position_noise.kind=none")
    apply_set(doc, "seeds=3")
    assert doc["variants"][0] == {"name": "c", "observer": {"eps": 0.5}}
    assert doc["scenario"]["sensors"] == {"position_noise": {"kind": "none"}} and doc["seeds"] == 3
    with pytest.raises(ConfigError, match="not a valid index"):
        apply_set(doc, "variants.5.name=x")
    apply_set(doc, "scenario.dt=1e-3")
    apply_set(doc, "variants.0.observer.eps=5.0e6")  # YAML 1.2 floats, as editors read them (PyYAML: strings)
    assert doc["scenario"]["dt"] == 1e-3 and doc["variants"][0]["observer"]["eps"] == 5e6
    apply_set(doc, "variants.0.name=1e5x")
    assert doc["variants"][0]["name"] == "1e5x"
    assert apply_set(doc, "variants.[1e5x].observer.eps=2") == ["variants.0.observer.eps"]  # a dot before [name] too


@pytest.mark.parametrize("key", [".seeds", "seeds.", "a..b", "variants[c]observer", "variants[]", "variants[c"])
def test_a_malformed_key_is_refused(key):
    """Before, a leading dot was read past (``.seeds=3`` set seeds) while ``a..b`` was refused."""
    doc = {"seeds": 1, "variants": [{"name": "c", "observer": {"eps": 1}}]}
    with pytest.raises(ConfigError, match="malformed key"):
        apply_set(doc, f"{key}=3")
    assert doc == {"seeds": 1, "variants": [{"name": "c", "observer": {"eps": 1}}]}


def test_apply_set_star_stands_for_every_key_or_item():
    doc = {"scenarios": {"S1": {"horizon": 40, "vessel": {"mass": 1}}, "S2-C1": {"horizon": 40}},
           "variants": [{"name": "a", "observer": {"eps": [1, 2]}}, {"name": "b"}]}
    assert apply_set(doc, "scenarios.*.vessel.thrust_time_constant=0.1") == [
        "scenarios.S1.vessel.thrust_time_constant", "scenarios.S2-C1.vessel.thrust_time_constant"]
    assert doc["scenarios"]["S1"]["vessel"] == {"mass": 1, "thrust_time_constant": 0.1}
    assert doc["scenarios"]["S2-C1"]["vessel"] == {"thrust_time_constant": 0.1}
    assert apply_set(doc, "variants.*.observer=[1, 2]") == ["variants.0.observer", "variants.1.observer"]
    doc["variants"][0]["observer"].append(3)  # each place holds its own copy of the value
    assert doc["variants"][1]["observer"] == [1, 2]
    assert apply_set(doc, "scenarios.*.*=7") == [f"scenarios.{s}.{k}" for s in ("S1", "S2-C1") for k in ("horizon", "vessel")]
    for bad, why in [("scenarios.S9.*=1", "no scenario 'S9' (have: S1, S2-C1)"),
                     ("variants.0.nope.*=1", "'*' has nothing to stand for: there is no 'nope'"),
                     ("variants.0.name.*=1", "scalar value ('a')"), ("scenarios.S1.*.x=1", "cannot descend into a int")]:
        with pytest.raises(ConfigError, match=re.escape(why)):
            apply_set(doc, bad)
    with pytest.raises(ConfigError, match=re.escape("one world, under 'scenario': set scenario.horizon")):
        apply_set({"scenario": {"horizon": 1}}, "scenarios.*.horizon=5")


def test_git_revision_marks_a_changed_source_tree_dirty(tmp_path):
    """The manifest's revision is that of the checkout holding the package, '-dirty' when its sources or
    configs differ from the commit (a copy of writer.py in a throwaway repository of the same layout), and
    'unknown' for a copy installed under the checkout."""
    import importlib.util
    import shutil
    import subprocess

    from marinebench.results import writer

    pkg = tmp_path / "marinebench" / "results"
    pkg.mkdir(parents=True)
    shutil.copy(writer.__file__, pkg / "writer.py")
    (tmp_path / "configs").mkdir()
    (tmp_path / "configs" / "a.yaml").write_text("seed: 1\n")
    git = ["git", "-c", "user.name=t", "-c", "user.email=t@t", "-C", str(tmp_path)]
    for cmd in (["init", "-q"], ["add", "-A"], ["commit", "-q", "-m", "c"]):
        subprocess.run(git + cmd, check=True)
    spec = importlib.util.spec_from_file_location("writer_copy", pkg / "writer.py")
    copy = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(copy)
    head = subprocess.run(git + ["rev-parse", "HEAD"], capture_output=True, text=True, check=True).stdout.strip()
    assert copy.git_revision() == head
    (tmp_path / "configs" / "a.yaml").write_text("seed: 2\n")
    assert copy.git_revision() == head + "-dirty"
    (tmp_path / "notes.txt").write_text("not a source\n")  # files outside the sources do not count
    (tmp_path / "configs" / "a.yaml").write_text("seed: 1\n")
    assert copy.git_revision() == head
    # an installed copy (pip install . into a .venv of the checkout) is not the checkout's code: HEAD may have
    # moved on since it was installed, so its revision is unknown (the manifest's source_digest names it)
    site = tmp_path / ".venv" / "lib" / "site-packages" / "marinebench" / "results"
    site.mkdir(parents=True)
    shutil.copy(writer.__file__, site / "writer.py")
    (tmp_path / ".gitignore").write_text(".venv/\n")
    spec = importlib.util.spec_from_file_location("writer_installed", site / "writer.py")
    installed = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(installed)
    assert installed.git_revision() == "unknown"
    assert copy.git_revision() == head  # the checkout's own copy still knows its commit


def test_summary_per_cell_in_order_of_first_appearance_diverged_runs_counted_not_averaged():
    import pandas as pd

    from marinebench.experiments.runner import summarise

    rng = np.random.default_rng(3)
    rows = []
    for variant in ("b", "a"):  # not sorted: the summary keeps the order the runs came in
        for seed in range(6):
            for signal in ("u", "r"):
                diverged = variant == "a" and signal == "u" and seed in (1, 4)
                rows.append(("S", variant, seed, signal, "std", np.nan if diverged else rng.random(),
                             "diverged" if diverged else "ok"))
    df = pd.DataFrame(rows, columns=["scenario", "variant", "seed", "signal", "metric", "value", "status"])
    df = df.sample(frac=1.0, random_state=1).reset_index(drop=True)  # cells interleaved
    out = summarise(df)
    first = df.drop_duplicates(["variant", "signal"])[["variant", "signal"]].apply(tuple, axis=1).tolist()
    assert list(zip(out["variant"], out["signal"])) == first
    for _, row in out.iterrows():
        cell = df[(df["variant"] == row["variant"]) & (df["signal"] == row["signal"])]
        good = cell.loc[cell["status"] == "ok", "value"].to_numpy()
        assert (row["n"], row["n_diverged"]) == (good.size, len(cell) - good.size)
        assert (row["mean"], row["ci_low"], row["ci_high"]) == mean_ci(good)
    assert out.set_index(["variant", "signal"]).loc[("a", "u"), "n_diverged"] == 2
    assert summarise(df.iloc[:0]).empty


def test_the_manifests_command_pastes_back_into_a_shell(monkeypatch):
    """A --set with spaces and braces (the c_ε grid's) was recorded unquoted, so copying the command failed."""
    argv = ["/venv/bin/marinebench", "sweep", "c_eps", "--set", 'sweep.params.c_eps={key: eps_scale, label: "c_ε"}']
    monkeypatch.setattr(writer.sys, "argv", argv)
    command = json.loads(writer.manifest())["command"]
    assert shlex.split(command) == ["marinebench", *argv[1:]]
    assert command.startswith("marinebench sweep c_eps --set 'sweep.params")


@pytest.mark.parametrize("what", ["file", "folder", "link"])
def test_someone_elses_file_or_folder_where_results_go_is_not_replaced(tmp_path, what):
    """A results folder is written whole in place of the previous one; what is at that path and is not marinebench's
    (a file, a folder without manifest.json, a symbolic link) is refused before anything runs and stays as it was.
    Before, `run --out DIR` replaced DIR/<config stem> whatever it was (a source folder named like the config)."""
    from typer.testing import CliRunner

    from marinebench.cli import app

    from .conftest import ROOT

    target = tmp_path / "asv_observers"
    if what == "file":
        target.write_text("precious")
    elif what == "folder":  # a web app's folder: its own manifest.json, no metrics.csv
        target.mkdir()
        (target / "important.py").write_text("code")
        (target / "manifest.json").write_text('{"name": "app"}')
    else:
        (tmp_path / "elsewhere").mkdir()
        target.symlink_to(tmp_path / "elsewhere")
    before = sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*"))
    config = ROOT / "examples" / "first_experiment" / "asv_observers.yaml"
    res = CliRunner().invoke(app, ["run", str(config), "--set", "scenario.horizon=6", "--seeds", "1", "--out",
                                   str(tmp_path), "--quiet"])
    said = {"file": "a file, not a results folder", "folder": "a folder of other files (no manifest.json and metrics.csv)",
            "link": "a symbolic link, not a results folder"}[what]
    assert res.exit_code == 2 and res.output.startswith(f"error: {target}: {said}"), res.output
    assert sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*")) == before
    with pytest.raises(ConfigError, match="not replaced"), atomic_directory(target):  # the Python API's write too
        pass
    empty = tmp_path / "empty"
    empty.mkdir()
    with atomic_directory(empty) as d:  # an empty folder holds nothing to lose
        (d / "manifest.json").write_text("{}")
        (d / "metrics.csv").write_text("")
    with atomic_directory(empty) as d:  # and a result is replaced by the next
        (d / "manifest.json").write_text("{}")
    assert sorted(p.name for p in empty.iterdir()) == ["manifest.json"]


def test_results_are_not_written_inside_a_results_folder(tmp_path):
    """``--out results/torben_fig1`` would put a result inside another, lost when that one is next replaced: refused
    before anything runs, by ``run``, ``sweep`` and the Python API's write, and nothing is created."""
    from typer.testing import CliRunner

    from marinebench.cli import app

    from .conftest import ROOT

    outer = tmp_path / "results" / "torben_fig1"
    outer.mkdir(parents=True)
    (outer / "manifest.json").write_text("{}")
    (outer / "metrics.csv").write_text("")
    before = sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*"))
    config = ROOT / "examples" / "first_experiment" / "asv_observers.yaml"
    cases = [(["run", str(config), "--set", "scenario.horizon=6", "--seeds", "1", "--out", str(outer / "more")],
              outer / "more" / "asv_observers"),
             (["sweep", "k", "--config", str(ROOT / "configs" / "torben_fig3.yaml"), "--n", "2", "--horizon", "2",
               "--gnss", "dgnss", "--out", str(outer)], outer / "torben_fig3_sweep_k_dgnss_n2_2s")]
    for args, target in cases:
        res = CliRunner().invoke(app, [*args, "--quiet"])
        assert res.exit_code == 2 and res.output.strip() == (
            f"error: {target}: inside the results folder {outer}, which is replaced whole when it is written again: "
            "not written there (choose another --out)"), res.output
    assert sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*")) == before
    with pytest.raises(ConfigError, match="inside the results folder"), atomic_directory(outer / "figures" / "x"):
        pass
    with atomic_directory(outer / "figures", results=False) as d:  # a result's own figures/ is written in it
        (d / "a.png").write_bytes(b"")
    assert (outer / "figures" / "a.png").exists()
