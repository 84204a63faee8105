"""Observers and controllers of your own (observers/custom.py, controllers/spec.py, plugins.py): the example
classes through the CLI, and every way such a class can be misconfigured, each one line naming the file and key,
exit code 2, nothing written."""

import hashlib
import json
import os
import shutil
import sys

import numpy as np
import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

from marinebench.cli import app
from marinebench.plugins import resolve_source, split_source, user_class

from .conftest import ROOT, md_row

EXAMPLE = ROOT / "examples" / "custom_observer"
runner = CliRunner()


@pytest.fixture
def example(tmp_path):
    """The example (and the scenarios it names) copied elsewhere: its relative paths resolve against the config."""
    shutil.copytree(EXAMPLE, tmp_path / "examples" / "mine")
    shutil.copytree(ROOT / "scenarios", tmp_path / "scenarios")
    return tmp_path / "examples" / "mine" / "earth_eso.yaml"


def test_example_runs_beside_liu_and_records_its_source(example, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # not the config's folder: the source is relative to the config file
    res = runner.invoke(app, ["run", str(example), "--set", "scenario.horizon=15", "--seeds", "2", "--out", "out", "--quiet"])
    assert res.exit_code == 0, res.output
    d = tmp_path / "out" / "earth_eso"
    m = pd.read_csv(d / "metrics.csv")
    std = m[m["metric"] == "std"].groupby(["variant", "signal"])["value"].mean()
    assert set(std.index.get_level_values("variant")) == {"liu_eps0.2", "liu_eps0.1", "earth_eso_w5", "earth_eso_w10"}
    # the same triple pole (w = 1/eps) and the same noise: the earth-frame ESO lands near Liu's body-frame ESO
    for w, eps in (("w5", "0.2"), ("w10", "0.1")):
        for s in ("u", "v", "sigma_u", "sigma_v"):
            assert std[f"earth_eso_{w}", s] == pytest.approx(std[f"liu_eps{eps}", s], rel=0.15), (w, s)
    assert std["earth_eso_w10", "u"] < std["earth_eso_w5", "u"] and std["earth_eso_w10", "sigma_u"] > std["earth_eso_w5", "sigma_u"]
    design = json.loads((d / "manifest.json").read_text())["designs"]["earth_eso_w5"]
    source = example.parent / "earth_eso.py"
    assert design["source"] == f"{source.resolve()}:EarthFrameEso" and design["params"] == {"omega": 5.0}
    assert design["sha256"] == hashlib.sha256(source.read_bytes()).hexdigest()


@pytest.fixture
def as_module(example, tmp_path, monkeypatch):
    """The example's class file as module ``<package>.eso`` of a package on sys.path (a name of its own per test:
    Python keeps an imported module for the process), and the config naming it by module, not by file."""
    package = f"lab_{hashlib.sha1(str(tmp_path).encode()).hexdigest()[:10]}"
    (tmp_path / "site" / package).mkdir(parents=True)
    (tmp_path / "site" / package / "__init__.py").write_text("")
    module = tmp_path / "site" / package / "eso.py"
    shutil.copy(example.parent / "earth_eso.py", module)
    monkeypatch.syspath_prepend(str(tmp_path / "site"))
    example.write_text(example.read_text().replace("source: earth_eso.py:", f"source: {package}.eso:"))
    yield example, module, f"{package}.eso:EarthFrameEso"
    for name in [name for name in sys.modules if name == package or name.startswith(f"{package}.")]:
        del sys.modules[name]


def test_a_module_source_runs_and_the_manifest_and_resume_key_name_its_file(as_module, tmp_path):
    """``package.module:Class`` is imported by name; its own file is what the manifest's sha256 and the resume key
    (provenance.inputs_key) hash, as for a ``.py`` source: an edited module makes the previous results stale."""
    from marinebench.loading import load_experiment
    from marinebench.provenance import custom_sources, inputs_key

    example, module, source = as_module
    res = runner.invoke(app, ["run", str(example), "--set", "scenario.horizon=6", "--seeds", "1",
                              "--out", str(tmp_path / "out"), "--quiet"])
    assert res.exit_code == 0, res.output
    design = json.loads((tmp_path / "out" / "earth_eso" / "manifest.json").read_text())["designs"]["earth_eso_w5"]
    assert design["source"] == source and design["sha256"] == hashlib.sha256(module.read_bytes()).hexdigest()
    exp, _ = load_experiment(example)
    assert custom_sources(exp) == [source]
    before = inputs_key(exp)
    module.write_text(module.read_text() + "\n# edited\n")
    assert inputs_key(exp) != before


def _write(path, text):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)


def test_the_files_a_module_source_imports_from_its_package_are_in_the_manifest_and_resume_key(as_module, tmp_path):
    """What the class's module imports of its own package (relatively or by name, directly or through one another,
    in a function too) is hashed with it, in the manifest and the resume key; a module of the package it does not
    import, and installed packages (numpy), are not."""
    from marinebench.loading import load_experiment
    from marinebench.plugins import source_files, source_record
    from marinebench.provenance import inputs_key

    example, module, source = as_module
    package = module.parent
    _write(package / "gains.py", "from .util import tools\nSCALE = 3.0\n")
    _write(package / "util" / "__init__.py", "")
    _write(package / "util" / "tools.py", f"def wrap(x):\n    from {package.name} import deep\n    return deep.wrap(x)\n")
    _write(package / "deep.py", "import numpy as np\n\n\ndef wrap(x):\n    return np.pi - np.mod(np.pi - x, 2 * np.pi)\n")
    _write(package / "unused.py", "X = 1\n")
    module.write_text(f"from . import gains\nimport {package.name}.util.tools\n" + module.read_text())
    mine = ["__init__.py", "deep.py", "gains.py", "util/__init__.py", "util/tools.py"]
    exp, _ = load_experiment(example)
    assert source_files(source) == [module, *(package / name for name in mine)]
    digests = {f"{package.name}/{name}": hashlib.sha256((package / name).read_bytes()).hexdigest() for name in mine}
    assert source_record(source) == (hashlib.sha256(module.read_bytes()).hexdigest(), digests)
    res = runner.invoke(app, ["run", str(example), "--set", "scenario.horizon=6", "--seeds", "1",
                              "--out", str(tmp_path / "out"), "--quiet"])
    assert res.exit_code == 0, res.output
    design = json.loads((tmp_path / "out" / "earth_eso" / "manifest.json").read_text())["designs"]["earth_eso_w5"]
    assert design["imports"] == digests and design["sha256"] == hashlib.sha256(module.read_bytes()).hexdigest()
    before = inputs_key(exp)
    (package / "unused.py").write_text("X = 2\n")
    assert inputs_key(exp) == before
    (package / "deep.py").write_text((package / "deep.py").read_text() + "\n# edited\n")
    assert inputs_key(exp) != before


def test_an_edited_helper_is_what_the_next_run_in_the_same_process_runs(as_module, tmp_path):
    """A notebook runs, edits a file the class imports, and runs again: the second run is the edited code (the class
    and its helper are imported again, not taken from the modules Python keeps), and its manifest hashes it. Here
    the helper doubles the bandwidth, so the edited omega = 5 variant is the first run's omega = 10 one."""
    import marinebench as mb

    example, module, _ = as_module
    helper = module.parent / "gains.py"
    _write(helper, "FACTOR = 1\n")
    old = "        self.omega = np.array("
    assert old in module.read_text()
    text = module.read_text().replace(old, old.replace("np.", "FACTOR * np."))
    module.write_text("from .gains import FACTOR\n" + text)
    exp = mb.load(example, sets=["scenario.horizon=6", "seeds=1"])
    std = [mb.run(exp, traces=False)]
    helper.write_text("FACTOR = 2.0\n")  # another size: Python's cached bytecode is checked by size and whole second
    std.append(mb.run(exp, traces=False))
    std = [r.metrics[r.metrics["metric"] == "std"].set_index(["variant", "signal", "seed"])["value"] for r in std]
    assert not np.allclose(std[1]["earth_eso_w5"], std[0]["earth_eso_w5"])
    assert np.allclose(std[1]["earth_eso_w5"], std[0]["earth_eso_w10"], rtol=1e-12, atol=0)
    design = json.loads((mb.write(mb.run(exp), tmp_path / "out") / "manifest.json").read_text())
    hashed = (module.parent / "__init__.py", helper)  # "from .gains" imports the package, then its module
    assert design["designs"]["earth_eso_w5"]["imports"] == {
        f"{module.parent.name}/{path.name}": hashlib.sha256(path.read_bytes()).hexdigest() for path in hashed}


def test_a_file_source_and_its_helper_are_imported_again_once_either_changes(tmp_path, monkeypatch):
    """plugins.user_class: the same class object while no file of it changes; a new one once its helper (a module
    found on sys.path) or its own file does, with the helper run again."""
    tag = hashlib.sha1(str(tmp_path).encode()).hexdigest()[:10]
    path, helper = tmp_path / "mine.py", tmp_path / f"helper_{tag}.py"
    _write(helper, "VALUE = 1\n")
    _write(path, f"import helper_{tag}\n\n\nclass Mine:\n    value = helper_{tag}.VALUE\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    source = f"{path}:Mine"
    try:
        first = user_class(source, ["value"])
        assert first.value == 1 and user_class(source, ["value"]) is first
        helper.write_text("VALUE = 22\n")
        second = user_class(source, ["value"])
        assert second is not first and second.value == 22 and user_class(source, ["value"]) is second
        path.write_text(path.read_text() + "    other = 3\n")
        assert user_class(source, ["value", "other"]).other == 3
        helper.unlink()
        with pytest.raises(ValueError, match=f"cannot import.*No module named 'helper_{tag}'"):
            user_class(source, ["value"])
    finally:
        sys.modules.pop(f"helper_{tag}", None)


def test_a_module_you_imported_and_edited_before_its_first_run_is_imported_again(tmp_path, monkeypatch):
    """The class of a module source imported before marinebench first uses it (by hand, in a notebook) is taken from
    the files on disk, with its package's helpers: not the modules Python kept from before they were edited. Another
    class of the module, used next, comes from the same import."""
    import importlib

    package = f"lab_{hashlib.sha1(str(tmp_path).encode()).hexdigest()[:10]}"
    _write(tmp_path / package / "__init__.py", "")
    _write(tmp_path / package / "gains.py", "VALUE = 1\n")
    _write(tmp_path / package / "mine.py", "from .gains import VALUE\n\n\nclass Mine:\n    value = VALUE\n\n\n"
                                            "class Other:\n    value = VALUE\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    try:
        assert importlib.import_module(f"{package}.mine").Mine.value == 1
        (tmp_path / package / "gains.py").write_text("VALUE = 22\n")
        mine = user_class(f"{package}.mine:Mine", ["value"])
        assert mine.value == 22
        other = user_class(f"{package}.mine:Other", ["value"])  # the module imported just now is not imported again
        assert sys.modules[f"{package}.mine"].Mine is mine and sys.modules[f"{package}.mine"].Other is other
    finally:
        for name in [name for name in sys.modules if name == package or name.startswith(f"{package}.")]:
            del sys.modules[name]


def test_a_file_source_is_hashed_with_the_files_of_its_folder_it_imports_and_their_errors_name_them(
        example, tmp_path, monkeypatch):
    """A ``.py`` source's own code is its folder (and below), less installed packages: a helper beside it that it
    imports (found on sys.path) is hashed with it, and an exception raised in the helper while the runs are
    simulated is one line naming the helper's file and line."""
    from marinebench.loading import load_experiment
    from marinebench.plugins import source_files, source_record
    from marinebench.provenance import inputs_key

    tag = hashlib.sha1(str(tmp_path).encode()).hexdigest()[:10]  # module names of their own: Python keeps them
    source, helper = example.parent / "earth_eso.py", example.parent / f"helper_{tag}.py"
    installed = example.parent / "venv" / "site-packages" / f"installed_{tag}.py"  # below the folder, yet not yours
    _write(helper, f"import numpy\nimport installed_{tag}\n\n\ndef check(obs):\n"
                   "    obs.calls = getattr(obs, 'calls', 0) + 1\n    if obs.calls > 400:\n"
                   "        raise ZeroDivisionError('late')\n")
    _write(installed, "X = 1\n")
    old = "        eta, zeta, a = xhat[:, 0:3], xhat[:, 3:6], xhat[:, 6:9]\n"
    text = source.read_text()
    assert old in text
    source.write_text(f"import helper_{tag}\n" + text.replace(old, old + f"        helper_{tag}.check(self)\n"))
    monkeypatch.syspath_prepend(str(installed.parent))
    monkeypatch.syspath_prepend(str(example.parent))
    try:
        exp, _ = load_experiment(example)
        name = exp.variants[2].observer.source
        assert source_files(name) == [source.resolve(), helper.resolve()]
        assert source_record(name)[1] == {helper.name: hashlib.sha256(helper.read_bytes()).hexdigest()}
        before = inputs_key(exp)
        installed.write_text("X = 2\n")
        assert inputs_key(exp) == before
        helper.write_text(helper.read_text() + "\n# edited\n")
        assert inputs_key(exp) != before
        res = runner.invoke(app, ["run", str(example), "--out", str(tmp_path / "out"), "--quiet", "--jobs", "1"])
        assert res.exit_code == 2 and res.output.strip() == (
            f"error: {example}: {helper.resolve()}, line 8, in check: ZeroDivisionError: late (a class of your own, "
            "while the runs were simulated)"), res.output
        assert not (tmp_path / "out").exists()
    finally:
        for module in (f"helper_{tag}", f"installed_{tag}"):
            sys.modules.pop(module, None)


def test_a_file_source_imports_the_helpers_beside_it_each_its_own(tmp_path, monkeypatch):
    """A ``.py`` source imports the files beside it as ``python file.py`` would, with nothing put on sys.path by
    hand: two configs in two folders, each with a class file importing a helper of the same name (``gains``, a
    FACTOR on ω), run by one ``run`` in one process, each run their own helper and hash it in their manifest. The
    folders end up last on sys.path, so they shadow no installed module."""
    from marinebench import plugins

    monkeypatch.setattr(sys, "path", list(sys.path))  # the folders this adds go with the test
    tag = hashlib.sha1(str(tmp_path).encode()).hexdigest()[:10]  # module names of their own: Python keeps them
    gains, eso = f"gains_{tag}", f"eso_{tag}"
    configs, design_a = [], None
    for folder, factor, omegas in (("a", "1", (5.0, 10.0)), ("b", "2.0", (5.0,))):
        _write(tmp_path / folder / f"{gains}.py", f"FACTOR = {factor}\n")
        shutil.copy(EXAMPLE / "earth_eso.py", tmp_path / folder / f"{eso}.py")
        _write(tmp_path / folder / "mine.py", f"import {gains}\nfrom {eso} import EarthFrameEso\n\n\n"
               "class Mine(EarthFrameEso):\n    def __init__(self, params, plant, dt):\n"
               f"        super().__init__([{{'omega': p['omega'] * {gains}.FACTOR}} for p in params], plant, dt)\n")
        variants = [{"name": f"w{w:g}", "observer": {"kind": "custom", "source": "mine.py:Mine", "params": {"omega": w}}}
                    for w in omegas]
        configs.append(tmp_path / folder / f"{folder}.yaml")
        configs[-1].write_text(yaml.safe_dump({"scenario": {"from": str(ROOT / "scenarios" / "cs2_noisy.yaml"),
                                                            "horizon": 10.0},
                                               "seeds": 2, "variants": variants, "metrics": [{"kind": "std"}]}))
    try:
        res = runner.invoke(app, ["run", *map(str, configs), "--out", str(tmp_path / "out"), "--quiet", "--jobs", "1"])
        assert res.exit_code == 0, res.output
        std = {folder: pd.read_csv(tmp_path / "out" / folder / "metrics.csv").set_index(["variant", "signal", "seed"])
               ["value"] for folder in "ab"}
        assert np.allclose(std["b"]["w5"], std["a"]["w10"], rtol=1e-12, atol=0)  # b's ω = 5 ran with b's FACTOR 2
        assert not np.allclose(std["b"]["w5"], std["a"]["w5"])
        for folder in "ab":
            design = json.loads((tmp_path / "out" / folder / "manifest.json").read_text())["designs"]["w5"]
            design_a = design_a if folder == "b" else design["imports"]
            assert design["imports"] == {f"{name}.py": hashlib.sha256((tmp_path / folder / f"{name}.py").read_bytes())
                                         .hexdigest() for name in (gains, eso)}, folder
            assert sys.path.index(str(tmp_path / folder)) > sys.path.index(str(plugins.Path(np.__file__).parents[1]))
        assert plugins.source_record(f"{tmp_path / 'a' / 'mine.py'}:Mine")[1] == design_a  # not b's, imported last
    finally:
        for name in (gains, eso):
            sys.modules.pop(name, None)


def test_a_source_that_cannot_be_imported_is_one_line_naming_file_and_key(example, tmp_path):
    """A module that is not there, or a class file raising as it is imported: one line, exit 2, nothing written, and
    the half-imported file is not left behind in sys.modules."""
    broken = example.parent / "broken.py"
    broken.write_text("raise RuntimeError('no licence for this observer')\n")
    for source, message in (
        ("nosuch_lab.eso:EarthFrameEso",
         "cannot import module 'nosuch_lab.eso' (ModuleNotFoundError: No module named 'nosuch_lab')"),
        ("broken.py:EarthFrameEso", f"{broken.resolve()}: cannot import (RuntimeError: no licence for this observer)"),
    ):
        config = example.parent / "edited.yaml"
        config.write_text(example.read_text().replace("source: earth_eso.py:EarthFrameEso", f"source: {source}", 1))
        res = runner.invoke(app, ["run", str(config), "--out", str(tmp_path / "out"), "--quiet"])
        assert res.exit_code == 2 and res.output.strip() == (
            f"error: {config}: variants.2.observer.source: {message}"), res.output
        assert not (tmp_path / "out").exists()
    assert not [m for m in list(sys.modules.values()) if getattr(m, "__file__", None) == str(broken.resolve())]


def test_a_custom_observer_parameter_sweeps_like_any_other(example, tmp_path):
    res = runner.invoke(app, ["sweep", "omega", "--config", str(example), "--n", "2", "--horizon", "8", "--seeds", "1",
                              "--out", str(tmp_path / "out"), "--quiet"])
    assert res.exit_code == 0, res.output
    m = pd.read_csv(tmp_path / "out" / "earth_eso_sweep_n2_8s" / "metrics.csv")
    u = m[(m["metric"] == "std") & (m["signal"] == "u")].sort_values("param_value")
    assert u["param_value"].tolist() == [1.0, 20.0] and u["value"].iloc[0] != u["value"].iloc[1]


def test_results_are_current_only_for_the_same_class_file(example):
    """``run --resume`` and a sweep's finished batches go by provenance.inputs_key, which covers the class file."""
    from marinebench.loading import load_experiment
    from marinebench.provenance import custom_sources, inputs_key

    exp, _ = load_experiment(example)
    source = example.parent / "earth_eso.py"
    assert custom_sources(exp) == [f"{source.resolve()}:EarthFrameEso"]
    before = inputs_key(exp)
    assert inputs_key(load_experiment(example)[0]) == before
    source.write_text(source.read_text() + "\n# edited\n")
    assert inputs_key(exp) != before


BROKEN = {
    "missing_file": ("source: nothere.py:EarthFrameEso", "variants.2.observer.source", "source file not found: /"),
    "missing_class": ("source: earth_eso.py:Nope", "variants.2.observer.source", "earth_eso.py has no class 'Nope'"),
    "bad_source": ("source: earth_eso.py", "variants.2.observer.source", "expected file.py:ClassName"),
    "bad_params": ("params: {omega: -1.0}", "variants.2.observer.params", "ValueError: omega must be positive"),
}


@pytest.mark.parametrize("case", sorted(BROKEN))
def test_a_broken_custom_observer_is_one_line_naming_file_and_key(example, tmp_path, case):
    edit, key, message = BROKEN[case]
    text = example.read_text()
    field = edit.split(":")[0]
    old = next(line for line in text.splitlines() if "omega: 5.0" in line and "custom" in line)
    new = old.replace("source: earth_eso.py:EarthFrameEso", edit) if field == "source" else old.replace("params: {omega: 5.0}", edit)
    example.write_text(text.replace(old, new))
    res = runner.invoke(app, ["run", str(example), "--out", str(tmp_path / "out"), "--quiet"])
    lines = res.output.strip().splitlines()
    assert res.exit_code == 2 and len(lines) == 1, res.output
    assert lines[0].startswith(f"error: {example}: {key}: ") and message in lines[0], lines[0]
    assert not (tmp_path / "out").exists()


def _config_beside(example, name, edit):
    """The example config edited by ``edit(doc)``, written beside it as ``name.yaml`` (its relative paths still resolve)."""
    doc = yaml.safe_load(example.read_text())
    edit(doc)
    path = example.parent / f"{name}.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


PROTOCOL = "    signals = ('u',)\n    scenario_kinds = ('open_loop_asv',)\n    n_state = 1\n" + "".join(
    f"    def {m}(self): pass\n" for m in ("init", "outputs", "max_rate"))
REFUSED = {  # a class file written beside the example (from the example's earth_eso.py) -> its class, the one line
    "partial": (lambda eso: "class Half:\n    signals = ('u',)\n    scenario_kinds = ('open_loop_asv',)\n", "Half",
                "partial.py) lacks n_state, init, outputs, max_rate"),
    "dp_only": (lambda eso: eso.replace('("open_loop_asv", "dp_supply")', '("dp_supply",)'), "EarthFrameEso",
                "EarthFrameEso does not apply to scenario kind open_loop_asv (its scenario_kinds: dp_supply)"),
    "no_step": (lambda eso: "class Half:\n" + PROTOCOL + "    discrete = True\n    def derivative(self): pass\n", "Half",
                "Half is discrete but lacks step"),
    "no_derivative": (lambda eso: "class Half:\n" + PROTOCOL + "    def step(self): pass\n", "Half",
                      "Half lacks derivative (or discrete = True and step)"),
    # the protocol's names and size, checked as such: before, a string was read as its letters ("lacks ['s', 'i',
    # ...]"), an empty tuple surfaced as unknown metric signals, and a repeated name or n_state = "9" passed
    "signals_a_string": (lambda eso: eso.replace('signals = ("u", "v", "r", "sigma_u", "sigma_v", "sigma_r")',
                                                'signals = "sigma_u"'), "EarthFrameEso",
                         "EarthFrameEso.signals is 'sigma_u': expected a tuple of names, e.g. ('u', 'v')"),
    "signals_empty": (lambda eso: eso.replace('signals = ("u", "v", "r", "sigma_u", "sigma_v", "sigma_r")', "signals = ()"),
                      "EarthFrameEso", "EarthFrameEso.signals is empty"),
    "signals_twice": (lambda eso: eso.replace('signals = ("u", "v",', 'signals = ("u", "u", "v",'), "EarthFrameEso",
                      "EarthFrameEso.signals names ['u'] more than once"),
    "kinds_a_string": (lambda eso: eso.replace('("open_loop_asv", "dp_supply")', '"open_loop_asv"'), "EarthFrameEso",
                       "EarthFrameEso.scenario_kinds is 'open_loop_asv': expected a tuple of names, e.g. ('open_loop_asv',)"),
    "n_state_text": (lambda eso: eso.replace("n_state = 9", 'n_state = "9"'), "EarthFrameEso",
                     "EarthFrameEso.n_state is '9': expected a whole number >= 1"),
}


@pytest.mark.parametrize("case", sorted(REFUSED))
def test_a_class_without_the_protocol_or_for_another_world_is_refused(example, case):
    """Missing protocol members, a world it does not apply to, or a discrete class without step (a continuous one
    without derivative): one line naming the file and key, exit 2."""
    text, cls, message = REFUSED[case]
    (example.parent / f"{case}.py").write_text(text((example.parent / "earth_eso.py").read_text()))
    path = _config_beside(example, case, lambda doc: doc["variants"][2]["observer"].update(source=f"{case}.py:{cls}"))
    res = runner.invoke(app, ["validate", str(path)])
    lines = res.output.strip().splitlines()
    assert res.exit_code == 2 and len(lines) == 1
    assert lines[0].startswith(f"error: {path}: variants.2.observer.source: ") and message in lines[0], res.output


def test_a_discrete_custom_observer_is_stepped_by_the_engine(example, tmp_path):
    """``discrete = True`` and ``step``: called once per engine step. A forward-Euler step of the example's ESO at
    dt = 5 ms (a triple pole at -5 rad/s, so w dt = 0.025) lands within a few % of the RK4-integrated class."""
    (example.parent / "euler_eso.py").write_text(  # files are loaded by path, not imported from a package
        (example.parent / "earth_eso.py").read_text() + "\n\n"
        "class EulerEso(EarthFrameEso):\n"
        "    discrete = True\n\n"
        "    def __init__(self, params, plant, dt):\n"
        "        super().__init__(params, plant, dt)\n"
        "        self.dt = dt\n\n"
        "    def step(self, xhat, y, tau, k):\n"
        "        return xhat + self.dt * self.derivative(xhat, y, tau)\n")

    def rk4_and_euler(doc):
        rk4 = doc["variants"][2]
        doc["variants"] = [rk4, {**rk4, "name": "euler_w5", "observer": {**rk4["observer"], "source": "euler_eso.py:EulerEso"}}]

    path = _config_beside(example, "euler", rk4_and_euler)
    res = runner.invoke(app, ["run", str(path), "--set", "scenario.horizon=10", "--seeds", "1", "--out", str(tmp_path / "out"), "--quiet"])
    assert res.exit_code == 0, res.output
    m = pd.read_csv(tmp_path / "out" / "euler" / "metrics.csv")
    std = m[m["metric"] == "std"].set_index(["variant", "signal"])["value"]
    for s in ("u", "v", "sigma_u", "sigma_v"):
        assert std["euler_w5", s] == pytest.approx(std["earth_eso_w5", s], rel=0.05) and std["euler_w5", s] != std["earth_eso_w5", s], s


WRONG_RETURNS = {  # an edit of earth_eso.py -> what the one-line error says
    "rate": (("        return float(self.omega.max())", '        return "fast"'),
             "EarthFrameEso.max_rate() returned 'fast': expected a finite number >= 0 (rad/s)"),
    "negative_rate": (("        return float(self.omega.max())", "        return -1.0"),
                      "EarthFrameEso.max_rate() returned -1.0: expected a finite number >= 0 (rad/s)"),
    "init": (("        return np.zeros((self.omega.size, self.n_state))", "        return np.zeros(self.n_state)"),
             "EarthFrameEso.init() has shape (9,): expected (B, n_state) = (1, 9)"),
    "missing": (('return {"u": u, ', "return {"), "EarthFrameEso.outputs() lacks ['u'], declared in its signals"),
    "undeclared": (('return {"u": u, ', 'return {"psi": psi, "u": u, '),  # before: a KeyError traceback in the engine
                   ("EarthFrameEso.outputs() returns ['psi'], not declared in its signals ['u', 'v', 'r', 'sigma_u', "
                    "'sigma_v', 'sigma_r']")),
    "shape": (('return {"u": u, ', 'return {"u": u[:0], '), "EarthFrameEso.outputs()['u'] has shape (0,): expected (B,) = (1,)"),
    # the derivative is called once too: before, these passed validation and failed in the engine with a traceback
    "derivative_shape": (("        return np.concatenate([zeta + 3 * w * e, acc_earth + a + 3 * w**2 * e, w**3 * e], axis=1)",
                          "        return np.concatenate([zeta + 3 * w * e, acc_earth + a + 3 * w**2 * e], axis=1)"),
                         "EarthFrameEso.derivative() returned ndarray of shape (1, 6): expected an array (B, n_state) = (1, 9)"),
    "derivative_list": (("        return np.concatenate([zeta + 3 * w * e, acc_earth + a + 3 * w**2 * e, w**3 * e], axis=1)",
                         "        return list(np.concatenate([zeta + 3 * w * e, acc_earth + a + 3 * w**2 * e, w**3 * e], axis=1))"),
                        "EarthFrameEso.derivative() returned list of shape (1, 9): expected an array (B, n_state) = (1, 9)"),
}


@pytest.mark.parametrize("case", sorted(WRONG_RETURNS))
def test_a_custom_observer_returning_the_wrong_thing_is_refused_before_running(example, tmp_path, case):
    """The built class is asked for max_rate, init and outputs at validation: a mistake in it is a config error
    naming the variant, not a traceback in the engine (or, for a bad shape, wrong numbers)."""
    (old, new), message = WRONG_RETURNS[case]
    source = example.parent / "earth_eso.py"
    assert old in source.read_text()
    source.write_text(source.read_text().replace(old, new))
    res = runner.invoke(app, ["run", str(example), "--out", str(tmp_path / "out"), "--quiet"])
    assert res.exit_code == 2 and res.output.strip() == f"error: {example}: variants.2.observer.source: {message}"
    assert not (tmp_path / "out").exists()


def test_an_exception_a_custom_observer_raises_while_running_is_one_line_naming_its_line(example, tmp_path):
    """A class that passes validation and raises later (here after 100 steps): one line naming its file, line and
    member; before, a traceback through the engine."""
    source = example.parent / "earth_eso.py"
    old = "        eta, zeta, a = xhat[:, 0:3], xhat[:, 3:6], xhat[:, 6:9]\n"
    text = source.read_text()
    assert old in text
    source.write_text(text.replace(old, old + "        self.calls = getattr(self, 'calls', 0) + 1\n"
                                   "        if self.calls > 400:\n            raise ZeroDivisionError('late')\n"))
    line = source.read_text().splitlines().index("            raise ZeroDivisionError('late')") + 1
    res = runner.invoke(app, ["run", str(example), "--out", str(tmp_path / "out"), "--quiet", "--jobs", "1"])
    assert res.exit_code == 2 and res.output.strip() == (
        f"error: {example}: {source.resolve()}, line {line}, in derivative: ZeroDivisionError: late (a class of your "
        "own, while the runs were simulated)"), res.output
    assert not (tmp_path / "out").exists()


LATE_ANSWERS = {  # what earth_eso.py's outputs/derivative return after 400 calls -> what the one-line error says
    # before: a stale estimate kept in the results (the last one given), or one broadcast to every run, rc 0
    "dropped": ("outputs", "out.pop('u')", "EarthFrameEso.outputs() lacks ['u'], declared in its signals"),
    "one_run": ("outputs", "out['u'] = out['u'][:1]", "EarthFrameEso.outputs()['u'] has shape (1,): expected (B,) = (2,)"),
    "scalar": ("outputs", "out['u'] = 0.0", "EarthFrameEso.outputs()['u'] has shape (): expected (B,) = (2,)"),
    # before: a traceback through the engine
    "not_a_dict": ("outputs", "out = None", "EarthFrameEso.outputs() returned NoneType: expected a dict of its signals"),
    "fewer_states": ("derivative", "out = out[:, :6]",
                     "EarthFrameEso.derivative() returned ndarray of shape (2, 6): expected an array (B, n_state) = (2, 9)"),
}


@pytest.mark.parametrize("case", sorted(LATE_ANSWERS))
def test_a_custom_observer_answering_wrong_while_running_is_one_line(example, tmp_path, case):
    """Every answer of a custom observer is checked while the runs are simulated too (observers/custom.py
    ``CheckedObserver``), not only at validation: a class that later drops a signal or changes a shape is one line,
    and nothing is written."""
    member, edit, message = LATE_ANSWERS[case]
    _answer_late(example.parent / "earth_eso.py", member, edit)
    res = runner.invoke(app, ["run", str(example), "--seeds", "1", "--set", "scenario.horizon=8", "--out",
                              str(tmp_path / "out"), "--quiet", "--jobs", "1"])
    assert res.exit_code == 2 and res.output.strip() == (
        f"error: {example}: {message} (a class of your own, while the runs were simulated)"), res.output
    assert not (tmp_path / "out").exists()


def test_a_custom_observer_answering_wrong_in_a_sweep_is_one_line_naming_the_config(example, tmp_path):
    """The same in ``sweep``, simulated in this process: named by the config, as ``run`` names it (before, the
    line lacked it)."""
    member, edit, message = LATE_ANSWERS["dropped"]
    _answer_late(example.parent / "earth_eso.py", member, edit)
    res = runner.invoke(app, ["sweep", "--config", str(example), "omega", "--n", "2", "--seeds", "1", "--horizon", "8",
                              "--jobs", "1", "--out", str(tmp_path / "out"), "--quiet"])
    assert res.exit_code == 2 and res.output.strip() == (
        f"error: {example}: {message} (a class of your own, while the runs were simulated)"), res.output


def test_a_custom_observer_failing_on_a_local_dask_worker_is_one_line_and_the_worker_stays_quiet(example, tmp_path,
                                                                                                   capfd):
    """On ``--dask local`` the failing chunk is reported once, by this process; before, its worker logged it too
    (an ERROR with the traceback), and the chunks cancelled after it as warnings, on the terminal's stderr."""
    member, edit, message = LATE_ANSWERS["dropped"]
    _answer_late(example.parent / "earth_eso.py", member, edit)
    res = runner.invoke(app, ["sweep", "--config", str(example), "omega", "--n", "2", "--seeds", "1", "--horizon", "8",
                              "--chunk-size", "1", "--dask", "local", "--workers", "1", "--out", str(tmp_path / "out"),
                              "--quiet"])
    assert res.exit_code == 2 and res.output.startswith("error: --dask: chunk 0 failed on a worker (UserCodeError: "
                                                        f"{message}"), res.output
    assert len(res.output.strip().splitlines()) == 1
    assert capfd.readouterr().err == ""


def _answer_late(source, member: str, edit: str) -> None:
    """Edit the example's class so that its ``member`` answers through ``edit`` (on ``out``) after 400 calls."""
    text = source.read_text()
    head = f"    def {member}(self"
    assert text.count(head) == 1
    source.write_text(text.replace(head, f"    def {member}(self, *args):\n        out = self._{member}(*args)\n"
                                         "        self.calls = getattr(self, 'calls', 0) + 1\n"
                                         f"        if self.calls > 400:\n            {edit}\n        return out\n\n"
                                         f"    def _{member}(self"))


def test_a_max_rate_of_zero_sets_no_step_limit_and_is_accepted(example):
    """``max_rate() == 0`` (no error dynamics to resolve) is a valid answer: only negative or non-finite ones are refused."""
    source = example.parent / "earth_eso.py"
    source.write_text(source.read_text().replace("        return float(self.omega.max())", "        return 0.0"))
    res = runner.invoke(app, ["validate", str(example)])
    assert res.exit_code == 0 and res.output.strip() == f"{example}: ok", res.output


CONTROLLER = ROOT / "examples" / "custom_controller"


@pytest.fixture
def controller_example(tmp_path):
    shutil.copytree(CONTROLLER, tmp_path / "examples" / "ctl")
    shutil.copytree(ROOT / "scenarios", tmp_path / "scenarios")
    return tmp_path / "examples" / "ctl" / "pid_s1.yaml"


def test_a_custom_controller_runs_in_the_closed_loop_and_sweeps(controller_example, tmp_path):
    res = runner.invoke(app, ["run", str(controller_example), "--set", "scenario.horizon=12", "--seeds", "2",
                              "--out", str(tmp_path / "out"), "--quiet"])
    assert res.exit_code == 0, res.output
    d = tmp_path / "out" / "pid_s1"
    m = pd.read_csv(d / "metrics.csv")
    rmse = m[m["metric"] == "rmse"].groupby(["variant", "signal"])["value"].mean()
    assert rmse["pid", "depth"] < 0.02 and rmse["pid", "yaw"] < 0.05  # it tracks: cm and a few degrees over the moves
    assert rmse["pid", "depth"] != rmse["cdo_pid", "depth"]  # feedback: cdo feeds it the CDO's estimates
    table = (d / "table.md").read_text()
    assert "rmse (depth [1e-2 m])" in table  # table.display applies to single-scenario tables too
    cell = md_row(table, "pid")[md_row(table, "variant").index("rmse (depth [1e-2 m])")]
    assert cell.startswith(f"{100 * rmse['pid', 'depth']:.3g} [")  # ours x 100, in the displayed unit
    designs = json.loads((d / "manifest.json").read_text())["designs"]
    source = controller_example.parent / "pid.py"
    assert designs["pid"]["controller"]["source"] == f"{source.resolve()}:Pid"
    assert designs["pid"]["controller_sha256"] == hashlib.sha256(source.read_bytes()).hexdigest()
    assert designs["pid"]["controller_imports"] == {}  # numpy only: nothing of its own
    res = runner.invoke(app, ["sweep", "depth_kp", "--config", str(controller_example), "--n", "2", "--horizon", "8",
                              "--seeds", "1", "--out", str(tmp_path / "out"), "--quiet"])
    assert res.exit_code == 0, res.output
    m = pd.read_csv(tmp_path / "out" / "pid_s1_sweep_depth_kp_n2_8s" / "metrics.csv")
    depth = m[(m["metric"] == "rmse") & (m["signal"] == "depth")].sort_values("param_value")
    assert depth["param_value"].tolist() == [100.0, 1600.0] and depth["value"].iloc[0] > depth["value"].iloc[1]


@pytest.mark.parametrize("edit, key, message", [
    ("source: pid.py:Nope", "variants.2.controller", "pid.py has no class 'Nope'"),
    ("source: pid.py:Pid, preset: table2_equivalent", "variants.2.controller",
     "a custom controller takes its settings in 'params' (not preset, depth, yaw)"),
    ("source: pid.py:Pid, params: {depth: {kq: 1.0}}", "variants.2.controller.params",
     "ValueError: unknown PID settings ['depth.kq']"),
    ("source: pid.py:Pid, params: {depth: {kp: .nan}}", "variants.2.controller.source",
     "Pid.command() at zero error returned [[nan, 0.0]]: expected finite values"),
])
def test_a_broken_custom_controller_is_one_line_naming_file_and_key(controller_example, tmp_path, edit, key, message):
    text = controller_example.read_text()
    old = "source: pid.py:Pid, params: {depth: {kp: 400.0}, yaw: {kp: 29.0}}"
    assert old in text
    controller_example.write_text(text.replace(old, edit, 1))
    res = runner.invoke(app, ["run", str(controller_example), "--out", str(tmp_path / "out"), "--quiet"])
    lines = res.output.strip().splitlines()
    assert res.exit_code == 2 and len(lines) == 1, res.output
    assert lines[0].startswith(f"error: {controller_example}: {key}: ") and message in lines[0], lines[0]
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(("edit", "got"), [("[:, :1]", "ndarray of shape (2, 1)"), ("[:1]", "ndarray of shape (1, 2)"),
                                           (".sum()", "float64 of shape ()"), (".tolist() and None", "NoneType of shape ()")])
def test_a_custom_controller_answering_wrong_while_running_is_one_line(controller_example, tmp_path, edit, got):
    """A custom controller's command is checked at every control step (controllers/spec.py ``CheckedController``): one
    column, one row or a scalar, after the first 50 commands, is one line; before, numpy broadcast it to every run
    and DOF and the run finished with rc 0 (wrong numbers)."""
    source = controller_example.parent / "pid.py"
    old = "        return self.kp * e1 + self.ki * self.integral + self.kd * e1_dot\n"
    text = source.read_text()
    assert old in text
    source.write_text(text.replace(old, old.replace("return", "tau =") + "        self.calls = getattr(self, 'calls', 0) + 1\n"
                                   f"        return tau if self.calls <= 50 else tau{edit}\n"))
    res = runner.invoke(app, ["run", str(controller_example), "--seeds", "2", "--set", "scenario.horizon=3",
                              "--out", str(tmp_path / "out"), "--quiet", "--jobs", "1"])
    assert res.exit_code == 2 and res.output.strip() == (
        f"error: {controller_example}: Pid.command() returned {got}: expected numbers (B, 2) = (2, 2), depth and yaw "
        "(a class of your own, while the runs were simulated)"), res.output
    assert not (tmp_path / "out").exists()


def test_a_source_names_a_file_or_module_and_a_class():
    assert split_source("pid.py:Pid") == ("pid.py", "Pid")
    assert split_source("package.module:Class") == ("package.module", "Class")
    for bad in ("Pid", ":Pid", "pid.py:", "pid.py:1x"):
        with pytest.raises(ValueError, match="expected file.py:ClassName or package.module:ClassName"):
            split_source(bad)


def test_only_a_relative_file_source_is_resolved_against_the_config(tmp_path):
    assert resolve_source("pid.py:Pid", tmp_path) == f"{(tmp_path / 'pid.py').resolve()}:Pid"
    absolute = f"{tmp_path / 'x' / 'pid.py'}:Pid"
    for unchanged in ("package.module:Class", absolute, "pid.py", None, 3):
        assert resolve_source(unchanged, tmp_path) == unchanged


def test_a_file_source_is_cached_until_it_changes(tmp_path):
    """plugins.user_class: the same class object while the file is unchanged, re-imported once its mtime moves."""
    path = tmp_path / "mine.py"
    path.write_text("class Mine:\n    value = 1\n")
    source = f"{path}:Mine"
    first = user_class(source, ["value"])
    assert first.value == 1 and user_class(source, ["value"]) is first
    path.write_text("class Mine:\n    value = 2\n")
    stat = path.stat()
    os.utime(path, ns=(stat.st_atime_ns, stat.st_mtime_ns + 10**9))
    assert user_class(source, ["value"]).value == 2


def test_the_classes_of_one_file_come_from_one_execution_of_it(tmp_path):
    """Two classes of one ``.py`` source (``mine.py:A``, ``mine.py:B``) come from one execution of the file, as two
    classes of a module come from one import: the module in ``sys.modules`` holds both (so either pickles), and
    after an edit the first class imported again serves the second."""
    import pickle

    tag = hashlib.sha1(str(tmp_path).encode()).hexdigest()[:10]
    path = tmp_path / "mine.py"
    _write(tmp_path / f"counter_{tag}.py", "RUNS = 0\n")
    _write(path, f"import counter_{tag}\n\ncounter_{tag}.RUNS += 1\n\n\nclass A:\n    value = 1\n\n\nclass B(A):\n    pass\n")
    try:
        for value in (1, 22):
            a, b = user_class(f"{path}:A", ["value"]), user_class(f"{path}:B", ["value"])
            module = sys.modules[a.__module__]
            assert (module.A, module.B, b.value) == (a, b, value) and sys.modules[f"counter_{tag}"].RUNS == 1
            assert pickle.loads(pickle.dumps(a)) is a and pickle.loads(pickle.dumps(b)) is b
            path.write_text(path.read_text().replace("value = 1", "value = 22"))  # the edit imports both again
    finally:
        sys.modules.pop(f"counter_{tag}", None)
