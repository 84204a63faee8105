"""Conformance over the registry (DESIGN.md: one suite runs every registered observer).

Every observer kind that ``marinebench list`` reports is run through the real config path (YAML document,
validation, preflight, runner) on a noiseless world of its own scenario kind, and must converge: its
largest error late in the run is a small fraction of its largest error early on. Registering a new
observer kind without a case here fails the first test.
"""

import numpy as np
import pytest
import yaml

from marinebench.experiments.runner import build_groups, plant_of, run, scenario_kinds_for
from marinebench.loading import load_experiment, load_scenario
from marinebench.preflight import preflight
from marinebench.registry import kinds

from .conftest import ROOT

CONSTANT = {"kind": "constant"}

# Open loop, constant thrust, torque and environment: CyberShip II settles in a steady turn, so the true
# lumped disturbance sigma is constant and an exact observer must reach it. Estimates start at 0.
STEADY_ASV = {
    "kind": "open_loop_asv", "name": "steady", "horizon": 40.0, "dt": 0.005,
    "inputs": {"F_u": {**CONSTANT, "value": 3.0}, "tau_r": {**CONSTANT, "value": 0.1}},
    "disturbances": {"F_wu": {**CONSTANT, "value": 0.3}, "F_wv": {**CONSTANT, "value": -0.2},
                     "tau_wr": {**CONSTANT, "value": 0.02}},
}
# The same vessel going straight (no torque, no environment): the NED bias the DP observers model is then constant
# once the surge has settled (in a steady turn it would rotate with the heading, which model (41) does not allow).
STRAIGHT_ASV = {
    "kind": "open_loop_asv", "name": "straight", "horizon": 80.0, "dt": 0.01,
    "inputs": {"F_u": {**CONSTANT, "value": 3.0}, "tau_r": {**CONSTANT, "value": 0.0}},
    "disturbances": {"F_wu": {**CONSTANT, "value": 0.0}, "F_wv": {**CONSTANT, "value": 0.0},
                     "tau_wr": {**CONSTANT, "value": 0.0}},
}
# Torben's sway impulse without waves, sensor errors, notch or model mismatch: the bias is constant after
# the impulse.
CLEAN_DP = {"from": str(ROOT / "scenarios" / "dp_impulse.yaml"), "horizon": 400.0, "waves": None,
            "vessel": {"kind": "supply_dp_linear"}, "design_vessel": None,
            "sensors": {"gnss_sigma": 0.0, "heading_sigma_deg": 0.0, "notch": False}}
# The ROV holding a pose with exact samples; the observers start 5 cm and 10 deg off.
CLEAN_ROV = {"from": str(ROOT / "scenarios" / "rov_s1.yaml"), "horizon": 10.0, "estimate_offset": [0.05, 10.0],
             "sensors": {"depth_noise": 0.0, "yaw_noise_deg": 0.0},
             "depth_ref": [[0, 0.1]], "yaw_ref_deg": [[0, 20.0]]}
DP_UNITS = {"bias_units": "10kN", "moment_arm": "L"}
# A custom observer (observers/custom.py): the example class users start from (exact for a disturbance constant in
# the earth frame, so on the straight run, like the DP observers).
EARTH_ESO = {"source": f"{ROOT / 'examples' / 'custom_observer' / 'earth_eso.py'}:EarthFrameEso"}
# ... and the closed-loop one (observers/custom_rov.py): a sampled-data ESO, exact for a constant disturbance
SAMPLED_ESO = {"source": f"{ROOT / 'examples' / 'custom_observer' / 'sampled_eso.py'}:SampledEso"}

# (kind, scenario, tunings to check, early window, late window): one case per observer kind and scenario kind
# it applies to (Bejarano's estimator and Liu's ESO also run in the DP world).
CASES = [
    ("liu_eso", STEADY_ASV, [{"eps": 0.1}, {"eps": 0.1, "mode": "fal"}], (0.0, 5.0), (35.0, None)),
    ("bejarano", STEADY_ASV, [{"delta_psi1": 1.0, "delta_p1": 1.0, "k_n": 1}, {}], (0.0, 5.0), (35.0, None)),
    ("npo", STRAIGHT_ASV, [{"bias_units": "force", "moment_arm": "L"}], (0.0, 10.0), (70.0, None)),
    ("resetting_fto", STRAIGHT_ASV, [{"bias_units": "force", "moment_arm": "L", "delta": 0.32, "eps": [0.2, 0.2, 0.02]}],
     (0.0, 10.0), (70.0, None)),
    ("npo", CLEAN_DP, [DP_UNITS], (0.0, 200.0), (350.0, None)),
    ("resetting_fto", CLEAN_DP, [{**DP_UNITS, "q2_scale": 1.0e8}], (0.0, 200.0), (350.0, None)),
    ("liu_eso", CLEAN_DP, [{"eps": 0.2}], (0.0, 200.0), (350.0, None)),
    ("bejarano", CLEAN_DP, [{"delta_psi1": 1.2, "delta_p1": 1.2}], (0.0, 200.0), (350.0, None)),
    ("custom", STRAIGHT_ASV, [{**EARTH_ESO, "params": {"omega": 10.0}}], (0.0, 10.0), (70.0, None)),
    ("custom", CLEAN_DP, [{**EARTH_ESO, "params": {"omega": 5.0}}], (0.0, 200.0), (350.0, None)),
    ("cdo", CLEAN_ROV, [{}], (0.0, 0.01), (8.0, None)),
    ("eo", CLEAN_ROV, [{}], (0.0, 0.01), (8.0, None)),
    ("custom", CLEAN_ROV, [{**SAMPLED_ESO, "params": {"omega_depth": 10.0, "omega_yaw": 10.0}}], (0.0, 0.01), (8.0, None)),
]
IDS = [f"{kind}-{load_scenario(scenario['from']).kind if 'from' in scenario else scenario['kind']}"
       for kind, scenario, *_ in CASES]


def test_every_registered_observer_kind_has_a_conformance_case_on_each_scenario_kind_it_applies_to():
    applies = {(kind, scenario) for kind in kinds()["observers"] for scenario in scenario_kinds_for(kind)}
    assert {kind for kind, *_ in CASES} == set(kinds()["observers"])
    assert {tuple(i.split("-")) for i in IDS} == applies


def experiment(tmp_path, case: tuple):
    kind, scenario, tunings, early, late = case
    closed_loop = scenario is CLEAN_ROV
    variants = [{"name": f"{kind}_{i}", "observer": {"kind": kind, **tuning},
                 **({"controller": {"kind": "rise"}} if closed_loop else {})} for i, tuning in enumerate(tunings)]
    window = [{"kind": "max_abs", "name": name, "t_start": a, **({"t_end": b} if b is not None else {})}
              for name, (a, b) in (("early", early), ("late", late))]
    doc = {"scenario": scenario, "seeds": 1, "variants": variants, "metrics": window,
           **({"engine": {"stiffness_limit": 2.0}} if scenario is CLEAN_DP else {})}
    path = tmp_path / f"{kind}.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    exp, _ = load_experiment(path)
    preflight(exp, path)
    return exp


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_observer_converges_on_a_noiseless_plant_of_its_own_model(tmp_path, case):
    m = run(experiment(tmp_path, case), traces=False).metrics
    assert (m["status"] == "ok").all()
    m = m[m["metric"].isin(["early", "late"])]
    values = m.pivot_table(index=["variant", "signal"], columns="metric", values="value")
    assert len(values) >= 2
    for (variant, signal), row in values.iterrows():
        assert row["late"] <= 1e-3 * row["early"] + 1e-9, (variant, signal, row["early"], row["late"])


@pytest.mark.parametrize("case", [c for c in CASES if c[1] is not CLEAN_ROV],
                         ids=[i for c, i in zip(CASES, IDS) if c[1] is not CLEAN_ROV])
def test_built_in_observers_keep_the_protocol_custom_ones_are_checked_against(tmp_path, case):
    """observers/custom.py's ``check_built`` on each batched built-in observer (three runs of each tuning):
    max_rate finite and >= 0, init() of shape (B, n_state), every declared signal as (B,). (The ROV's CDO and EO
    are part of its world, not batched observers.)"""
    from marinebench.observers.custom import check_built

    exp = experiment(tmp_path, case)
    run_variant = np.repeat(np.arange(len(exp.variants)), 3)
    (group,) = build_groups(exp, run_variant, plant_of(exp.scenario))
    check_built(group.observer, len(run_variant))
