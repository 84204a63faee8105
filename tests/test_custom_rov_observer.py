"""Observers of your own in the closed-loop ROV world (observers/custom_rov.py): a class that restates the world's
own EO, or the held samples a measurement-fed controller gets, gives the same loop and estimates to the bit; the
example runs; every way such a class or variant can be misconfigured is one line naming the file and key."""

import json
import shutil

import numpy as np
import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

from marinebench.cli import app

from .conftest import ROOT

runner = CliRunner()

EO_COPY = '''
import numpy as np
from marinebench.observers.cdo import EoParams


class EoCopy:
    """The world's extended high-gain observer (observers/cdo.py, the EO) restated as a class of your own."""

    scenario_kinds = ("rov_tracking",)
    signals = ("depth", "yaw", "depth_rate", "yaw_rate")
    n_state = 6

    def __init__(self, params, plant, dt):
        if any(p.get("eps", 1.0) <= 0 for p in params):
            raise ValueError("eps must be positive")
        self.eo = EoParams(**params[0])
        self.gain, self.inertia, self.start = self.eo.gain(), plant.inertia, plant.initial

    def init(self):
        x = np.zeros((len(self.start), 2, 3))
        x[:, :, 0] = self.start
        return x.reshape(-1, 6)

    def derivative(self, xhat, y, tau):
        x = xhat.reshape(-1, 2, 3)
        acc = tau / self.inertia
        flow = np.stack([x[..., 1], x[..., 2] + acc, np.zeros_like(acc)], axis=-1)
        return (flow + self.gain * (y - x[..., 0])[..., None]).reshape(-1, 6)

    def outputs(self, xhat):
        x = xhat.reshape(-1, 2, 3)
        return {"depth": x[:, 0, 0], "yaw": x[:, 1, 0], "depth_rate": x[:, 0, 1], "yaw_rate": x[:, 1, 1]}

    def max_rate(self):
        return self.eo.max_rate()


class EoWithDisturbance(EoCopy):
    """The same, also reporting its lumped-disturbance estimate x_hat_3 of each DOF (or of yaw only: params)."""

    signals = ("depth", "yaw", "depth_rate", "yaw_rate", "depth_disturbance", "yaw_disturbance")

    def outputs(self, xhat):
        x = xhat.reshape(-1, 2, 3)
        return super().outputs(xhat) | {"depth_disturbance": x[:, 0, 2], "yaw_disturbance": x[:, 1, 2]}


class EoYawDisturbance(EoCopy):
    signals = ("depth", "yaw", "depth_rate", "yaw_rate", "yaw_disturbance")

    def outputs(self, xhat):
        return super().outputs(xhat) | {"yaw_disturbance": xhat.reshape(-1, 2, 3)[:, 1, 2]}


class Held:
    """The held samples and their differences: what the world feeds a controller with feedback measured."""

    scenario_kinds = ("rov_tracking",)
    signals = ("depth", "yaw", "depth_rate", "yaw_rate")
    n_state = 4
    discrete = True

    def __init__(self, params, plant, dt):
        self.every, self.dt, self.n = [round(h / dt) for h in plant.sample_periods], dt, len(params)

    def init(self):
        return np.zeros((self.n, 4))

    def step(self, xhat, y, tau, k):
        x = xhat.reshape(-1, 2, 2)
        for dof, every in enumerate(self.every):
            if k % every == 0:
                if k > 0:
                    x[:, dof, 1] = (y[:, dof] - x[:, dof, 0]) / (every * self.dt)
                x[:, dof, 0] = y[:, dof]
        return x.reshape(-1, 4)

    def outputs(self, xhat):
        x = xhat.reshape(-1, 2, 2)
        return {"depth": x[:, 0, 0], "yaw": x[:, 1, 0], "depth_rate": x[:, 0, 1], "yaw_rate": x[:, 1, 1]}

    def max_rate(self):
        return 0.0
'''

SRISE = {"kind": "srise", "output_scale": [40.0, 9.81]}
OBSERVED = ["depth", "yaw", "depth_rate", "yaw_rate", "depth_meas", "yaw_meas"]


def _config(tmp_path, variants: list[dict], name: str = "mine") -> str:
    (tmp_path / "classes.py").write_text(EO_COPY)
    doc = {"scenario": {"from": str(ROOT / "scenarios" / "rov_s1.yaml"), "horizon": 4.0, "estimate_offset": [0.05, 10.0]},
           "seeds": 2, "variants": variants,
           "metrics": [{"kind": "rmse", "name": "rmse", "t_start": 0.0, "signals": OBSERVED},
                       {"kind": "rmse", "name": "each", "t_start": 0.0,
                        "signals": ["depth_cdo", "yaw_cdo", "depth_eo", "yaw_eo"]},
                       {"kind": "rmse", "name": "dist", "t_start": 0.0, "signals": ["depth_disturbance", "yaw_disturbance"]},
                       {"kind": "int", "name": "int"}]}
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return str(path)


def _run(tmp_path, variants: list[dict]) -> pd.Series:
    res = runner.invoke(app, ["run", _config(tmp_path, variants), "--out", str(tmp_path / "out"), "--quiet"])
    assert res.exit_code == 0, res.output
    m = pd.read_csv(tmp_path / "out" / "mine" / "metrics.csv")
    assert (m["status"] == "ok").all()
    return m.set_index(["variant", "seed", "metric", "signal"])["value"]


def _same(values: pd.Series, a: str, b: str, metrics: tuple[str, ...]) -> None:
    left = values.loc[a].loc[:, list(metrics)].sort_index()
    right = values.loc[b].loc[:, list(metrics)].sort_index()
    assert list(left.index) == list(right.index) and len(left) > 0
    np.testing.assert_array_equal(left.to_numpy(), right.to_numpy())


def test_a_custom_observer_restating_the_eo_reports_and_feeds_the_loop_as_the_eo_does(tmp_path):
    """The EO as a class of your own: watched (the loop fed by the CDO) it reports the world's EO estimates, and fed
    to the controller (feedback custom) it closes the same loop as feedback eo, to the bit: the same state, RK4
    stages, held samples and command. The two loops differ from each other (the feedback is not ignored). INT starts
    when the tracking error, not the reported observer's error, is within its tolerance: the same loop seen through
    the CDO has the same INT (before: not, 139 vs 145 N^2 s on S1 in yaw)."""
    mine = {"kind": "custom", "source": "classes.py:EoCopy"}
    values = _run(tmp_path, [
        {"name": "cdo_watch", "controller": {**SRISE, "feedback": "cdo"}, "observer": {"kind": "cdo"}},
        {"name": "eo_watch", "controller": {**SRISE, "feedback": "cdo"}, "observer": {"kind": "eo"}},
        {"name": "copy_watch", "controller": {**SRISE, "feedback": "cdo"}, "observer": mine},
        {"name": "eo_fed", "controller": {**SRISE, "feedback": "eo"}, "observer": {"kind": "eo"}},
        {"name": "copy_fed", "controller": {**SRISE, "feedback": "custom"}, "observer": mine},
    ])
    _same(values, "eo_watch", "copy_watch", ("rmse", "each", "int"))
    assert "dist" not in values.loc["copy_watch"].index.get_level_values("metric")  # it estimates no disturbance
    _same(values, "eo_watch", "cdo_watch", ("each", "int"))
    _same(values, "eo_fed", "copy_fed", ("rmse", "each", "int"))
    assert values.loc["eo_fed", :, "int", "depth"].ne(values.loc["eo_watch", :, "int", "depth"]).all()


def test_a_custom_observer_estimating_the_disturbance_feeds_it_forward_as_the_eo_does(tmp_path):
    """A class that also reports its disturbance estimates (depth_disturbance, yaw_disturbance) feeds them forward,
    with disturbance_feedforward, as the EO's x_hat_3 is: the same loop as feedback eo with feedforward, to the bit,
    in both DOF or in yaw alone (a class estimating only yaw's disturbance); and a different loop from the one
    without feedforward."""
    both = {"kind": "custom", "source": "classes.py:EoWithDisturbance"}
    yaw_only = {"kind": "custom", "source": "classes.py:EoYawDisturbance"}
    values = _run(tmp_path, [
        {"name": "eo_ff", "controller": {**SRISE, "feedback": "eo", "disturbance_feedforward": True},
         "observer": {"kind": "eo"}},
        {"name": "copy_ff", "controller": {**SRISE, "feedback": "custom", "disturbance_feedforward": True},
         "observer": both},
        {"name": "eo_ff_yaw", "controller": {**SRISE, "feedback": "eo", "disturbance_feedforward": [False, True]},
         "observer": {"kind": "eo"}},
        {"name": "copy_ff_yaw", "controller": {**SRISE, "feedback": "custom", "disturbance_feedforward": [False, True]},
         "observer": yaw_only},
        {"name": "copy_fed", "controller": {**SRISE, "feedback": "custom"}, "observer": both},
    ])
    _same(values, "eo_ff", "copy_ff", ("rmse", "each", "int", "dist"))  # dist: the class's own d against the truth
    _same(values, "eo_ff_yaw", "copy_ff_yaw", ("rmse", "each", "int"))
    assert values.loc["copy_ff_yaw", :, "dist"].index.get_level_values("signal").unique().tolist() == ["yaw_disturbance"]
    np.testing.assert_array_equal(values.loc["copy_ff_yaw", :, "dist", "yaw_disturbance"],
                                  values.loc["eo_ff_yaw", :, "dist", "yaw_disturbance"])
    assert values.loc["copy_ff", :, "int", "yaw"].ne(values.loc["copy_fed", :, "int", "yaw"]).all()
    assert values.loc["copy_ff", :, "int", "depth"].ne(values.loc["copy_ff_yaw", :, "int", "depth"]).all()


def test_a_discrete_custom_observer_of_the_held_samples_closes_the_measured_loop(tmp_path):
    """``discrete = True``: stepped at the start of every engine step after its samples and before the command, so a
    class holding the samples and differencing them (as the world does for feedback measured) closes the same loop:
    the same commands and the same CDO and EO estimates in every run, to the bit."""
    values = _run(tmp_path, [
        {"name": "measured", "controller": {**SRISE, "feedback": "measured"}},
        {"name": "held", "controller": {**SRISE, "feedback": "custom"},
         "observer": {"kind": "custom", "source": "classes.py:Held"}},
        {"name": "cdo_fed", "controller": {**SRISE, "feedback": "cdo"}},
    ])
    _same(values, "measured", "held", ("each", "int"))
    assert values.loc["cdo_fed", :, "int", "depth"].ne(values.loc["measured", :, "int", "depth"]).all()


def test_the_sampled_eso_example_runs_beside_the_cdo_and_the_eo(tmp_path, monkeypatch):
    """examples/custom_observer/sampled_eso.yaml, copied elsewhere: its quick profile runs, the manifest records the
    class's file, and the loop closed through it (srise_sampled_eso) differs from the one it only watches, and from the
one that also feeds its disturbance estimate forward (sampled_eso_srise)."""
    folder = tmp_path / "examples" / "mine"
    shutil.copytree(ROOT / "examples" / "custom_observer", folder)
    shutil.copytree(ROOT / "scenarios", tmp_path / "scenarios")
    monkeypatch.chdir(tmp_path)
    res = runner.invoke(app, ["run", str(folder / "sampled_eso.yaml"), "--profile", "quick", "--out", "out", "--quiet"])
    assert res.exit_code == 0, res.output
    m = pd.read_csv(tmp_path / "out" / "sampled_eso" / "metrics.csv")
    assert (m["status"] == "ok").all() and m["seed"].nunique() == 2
    rmse = m[m.metric == "rmse"].groupby(["variant", "signal"])["value"].mean()
    assert rmse["sampled_eso", "depth"] < 0.01 and rmse["sampled_eso", "yaw"] < 0.02  # m, rad: it tracks the truth
    ints = m[m.metric == "int"].groupby(["variant", "signal"])["value"].mean()
    assert ints["srise_sampled_eso", "depth"] != ints["srise_cdo", "depth"]
    assert ints["sampled_eso_srise", "depth"] != ints["srise_sampled_eso", "depth"]  # its disturbance fed forward
    design = json.loads((tmp_path / "out" / "sampled_eso" / "manifest.json").read_text())["designs"]["sampled_eso"]
    assert design["observer"]["source"] == f"{(folder / 'sampled_eso.py').resolve()}:SampledEso"
    assert design["observed_through"] == "custom" and len(design["observer"]["sha256"]) == 64


BROKEN = {  # an edit of the variant (its observer and controller) or of the class file -> key, the one line
    "feedback_without_observer": (
        lambda v: v.update(controller={**SRISE, "feedback": "custom"}, observer={"kind": "cdo"}), None,
        "variants.0", "feedback 'custom' feeds the controller the variant's own observer: give observer: {kind: custom"),
    "feedforward_measured": (
        lambda v: v["controller"].update(feedback="measured", disturbance_feedforward=True), None,
        "variants.0.controller", "disturbance_feedforward needs feedback 'cdo', 'eo' or 'custom'"),
    "feedforward_without_estimate": (
        lambda v: v["controller"].update(disturbance_feedforward=[False, True]), None,
        "variants.0", ("disturbance_feedforward with feedback 'custom' feeds forward the observer's yaw_disturbance, "
                       "not among its signals ['depth', 'yaw', 'depth_rate', 'yaw_rate']")),
    "other_world": (
        None, lambda text: text.replace('scenario_kinds = ("rov_tracking",)\n    signals = ("depth", "yaw", "depth_rate", '
                                        '"yaw_rate")\n    n_state = 6', 'scenario_kinds = ("open_loop_asv",)\n    signals = '
                                        '("depth", "yaw", "depth_rate", "yaw_rate")\n    n_state = 6'),
        "variants.0.observer.source", "EoCopy does not apply to scenario kind rov_tracking (its scenario_kinds: open_loop_asv)"),
    "other_signals": (
        None, lambda text: text.replace('signals = ("depth", "yaw", "depth_rate", "yaw_rate")\n    n_state = 6',
                                        'signals = ("depth", "yaw")\n    n_state = 6'),
        "variants.0.observer.source", ("EoCopy.signals is ('depth', 'yaw'): an observer of a rov_tracking world "
                                       "estimates depth, yaw, depth_rate, yaw_rate (and may estimate "
                                       "depth_disturbance and yaw_disturbance)")),
    "params_refused": (
        lambda v: v["observer"].update(params={"eps": -1.0}), None,
        "variants.0.observer.params", "ValueError: eps must be positive"),
    "multiline_message": (  # a class's exception of several lines is still one line
        lambda v: v["observer"].update(params={"eps": -1.0}),
        lambda text: text.replace('raise ValueError("eps must be positive")',
                                  'raise ValueError("eps must be positive:\\n\\n    eps = 0.01 is a good start\\n")'),
        "variants.0.observer.params", "ValueError: eps must be positive: / eps = 0.01 is a good start"),
    "wrong_shape": (
        None, lambda text: text.replace("return (flow + self.gain * (y - x[..., 0])[..., None]).reshape(-1, 6)",
                                        "return flow"),
        "variants.0.observer.source", ("EoCopy.derivative() returned ndarray of shape (1, 2, 3): expected an array "
                                       "(B, n_state) = (1, 6)")),
}


@pytest.mark.parametrize("case", sorted(BROKEN))
def test_a_misconfigured_closed_loop_custom_observer_is_one_line_naming_file_and_key(tmp_path, case):
    edit_variant, edit_class, key, message = BROKEN[case]
    variant = {"name": "mine", "controller": {**SRISE, "feedback": "custom"},
               "observer": {"kind": "custom", "source": "classes.py:EoCopy"}}
    if edit_variant is not None:
        edit_variant(variant)
    path = _config(tmp_path, [variant])
    if edit_class is not None:
        text = (tmp_path / "classes.py").read_text()
        assert edit_class(text) != text
        (tmp_path / "classes.py").write_text(edit_class(text))
    res = runner.invoke(app, ["run", path, "--out", str(tmp_path / "out"), "--quiet"])
    lines = res.output.strip().splitlines()
    assert res.exit_code == 2 and len(lines) == 1, res.output
    assert lines[0].startswith(f"error: {path}: {key}: ") and message in lines[0], res.output
    assert not (tmp_path / "out").exists()
