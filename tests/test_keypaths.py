"""Config errors name the key as written in YAML: pydantic's location without union tags or member types."""

import copy
from pathlib import Path
from typing import Literal

import pytest
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from marinebench.config import Experiment
from marinebench.errors import ConfigError
from marinebench.keypaths import key_path, near_misses, nested_keys, unknown_key_hint
from marinebench.loading import load_scenario, resolve_document


def first_error(root, doc):
    from pydantic import TypeAdapter

    with pytest.raises(ValidationError) as exc:
        TypeAdapter(root).validate_python(doc)
    return exc.value.errors()[0]


CONFIGS = Path(__file__).parent.parent / "configs"


def experiment(**variant):
    """A valid experiment document (Table IV's config, resolved) with one variant replaced."""
    doc, _ = resolve_document(CONFIGS / "bejarano_table4.yaml")
    doc["variants"] = [{"name": "a", "observer": {"kind": "liu_eso", "eps": 0.1}} | variant]
    doc.pop("claims")
    doc.pop("table")
    return doc


def test_discriminated_union_tags_are_dropped():
    err = first_error(Experiment, experiment(observer={"kind": "bejarano", "delta": 1}))
    assert err["loc"][:4] == ("variants", 0, "observer", "bejarano")  # what pydantic says
    key, allowed = key_path(Experiment, err["loc"], unknown=True)
    assert key == "variants.0.observer.delta"
    assert {"delta_p1", "delta_psi1", "k_omega"} <= set(allowed) and "eps" not in allowed


def test_a_plain_unions_member_type_is_dropped():
    err = first_error(Experiment, experiment(controller={"kind": "srise", "output_scale": "x"}))
    assert any("[" in str(p) or p == "float" for p in err["loc"])  # pydantic names the member it tried
    assert key_path(Experiment, err["loc"])[0] == "variants.0.controller.output_scale"


def test_claim_and_metric_kinds_are_dropped():
    doc = experiment() | {"claims": [{"kind": "order", "signals": ["u"]}], "metrics": [{"kind": "std", "bogus": 1}]}
    with pytest.raises(ValidationError) as exc:
        Experiment.model_validate(doc)
    keys = {key_path(Experiment, e["loc"], e["type"] == "extra_forbidden")[0] for e in exc.value.errors()}
    assert "metrics.0.bogus" in keys and any(k.startswith("claims.0.") for k in keys)
    assert not any(".order" in k or ".std" in k for k in keys), keys


def test_dict_values_keep_their_key():
    err = first_error(Experiment, experiment(tags={"gnss": ["x"]}))
    assert key_path(Experiment, err["loc"])[0] == "variants.0.tags.gnss"


def test_scenario_file_of_another_kind(tmp_path):
    f = tmp_path / "dp.yaml"
    f.write_text(f"from: {CONFIGS.parent / 'scenarios' / 'dp_impulse.yaml'}\nsensors: {{notch_wo: 1.0}}\n")
    with pytest.raises(ConfigError) as exc:
        load_scenario(f)
    message = str(exc.value)
    assert message.startswith(f"{f}: sensors.notch_wo: unknown key (did you mean ") and "notch_w0" in message, message


def test_hint_lists_the_allowed_keys_without_a_near_miss():
    assert unknown_key_hint("a.zzz", ["alpha", "beta"]) == " (allowed here: alpha, beta)"
    assert unknown_key_hint("a.zzz", [f"k{i}" for i in range(20)], most=2) == " (allowed here: k0, k1, …)"
    assert unknown_key_hint("a.alpah", ["alpha", "beta"]) == " (did you mean alpha?)"
    assert unknown_key_hint("zzz", []) == ""
    assert unknown_key_hint("notch_wo", ["notch", "notch_w0", "notch_wc"]) == " (did you mean notch_w0, notch_wc or notch?)"
    assert unknown_key_hint("vessel.xuu", ["X_u", "X_uu", "Y_v"]) == " (did you mean X_uu or X_u?)"  # case aside


def test_a_key_at_the_wrong_level_is_found_further_down():
    doc = experiment() | {"horizon": 10}
    with pytest.raises(ValidationError) as exc:
        Experiment.model_validate(doc)
    key, allowed = key_path(Experiment, exc.value.errors()[0]["loc"], unknown=True)
    assert key == "horizon" and "horizon" not in allowed
    assert unknown_key_hint(key, allowed) == " (did you mean scenario.horizon or scenarios.<name>.horizon?)"
    doc = experiment() | {"k_omega": 1}
    with pytest.raises(ValidationError) as exc:
        Experiment.model_validate(doc)
    assert unknown_key_hint(*key_path(Experiment, exc.value.errors()[0]["loc"], unknown=True)) == (
        " (did you mean variants.<i>.observer.k_omega?)")
    # a near miss beside the key wins over the same name further down
    assert unknown_key_hint("seeed", ["seed", "seeds", "scenario.seeed"]) == " (did you mean seed or seeds?)"


def _leaves(node, prefix=()):
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _leaves(v, (*prefix, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _leaves(v, (*prefix, i))
    elif prefix:
        yield prefix


def _resolves(node, parts) -> bool:
    """``parts`` lead through ``node`` (a name with dots, e.g. the variant ``liu_eps0.2``, spans several parts)."""
    if not parts:
        return True
    if isinstance(node, list):
        return parts[0].isdigit() and int(parts[0]) < len(node) and _resolves(node[int(parts[0])], parts[1:])
    if isinstance(node, dict):
        return any(".".join(parts[:n]) in node and _resolves(node[".".join(parts[:n])], parts[n:])
                   for n in range(1, len(parts) + 1))
    return False


@pytest.mark.parametrize("config", ["bejarano_table4", "tijjani_table3", "torben_fig3"])
def test_every_bad_leaf_is_named_by_a_key_of_the_document(config):
    """Each leaf of a committed config set to a wrong-typed value, or given an unknown key beside it: the error's
    key is a path of the document as written (every part but a missing last one exists in it), so no tag or
    member type of pydantic's location is left in it."""
    from marinebench.loading import validation_to_config_error

    doc, origins = resolve_document(CONFIGS / f"{config}.yaml")
    checked = 0
    for path in _leaves(doc):
        for value in ("not-a-number", {"zzz_extra": 1}):
            bad = copy.deepcopy(doc)
            node = bad
            for p in path[:-1]:
                node = node[p]
            node[path[-1]] = value
            try:
                Experiment.model_validate(bad)
            except ValidationError as exc:
                error = validation_to_config_error(exc, origins)
                parts = error.key.split(".")
                assert _resolves(bad, parts[:-1]), (path, value, str(error))
                checked += 1
    assert checked > 50


class _Gain(BaseModel):
    """A model whose kind's value is also one of its field names (only a union's member is named by its tag)."""

    model_config = ConfigDict(extra="forbid")
    kind: Literal["gain"] = "gain"
    gain: float = 1.0


class _Leaf(BaseModel):
    horizon: float = 1.0


class _Mid(BaseModel):
    leaf: _Leaf = _Leaf()


class _Deep(BaseModel):
    mid: _Mid = _Mid()


class _Root(BaseModel):
    gain: _Gain = _Gain()
    deep: _Deep = _Deep()  # horizon three keys down (deep.mid.leaf.horizon: four)
    side: _Leaf = _Leaf()  # horizon one key down (side.horizon)
    b_mid: _Mid = _Mid()  # two down (b_mid.leaf.horizon), before 'side' by name, after it by depth


def test_a_single_models_kind_value_is_a_key_not_a_tag():
    err = first_error(_Root, {"gain": {"gain": "x"}})
    assert err["loc"] == ("gain", "gain")
    assert key_path(_Root, err["loc"])[0] == "gain.gain"


def test_keys_further_down_come_shortest_first_and_at_most_three_deep():
    assert nested_keys([_Root], "horizon") == ["side.horizon", "b_mid.leaf.horizon"]


def test_a_near_miss_is_found_whatever_its_case():
    assert near_misses("vessel.xuu", ["X_uu", "X_u", "Y_v"])[0] == "X_uu"
    assert near_misses("VESSEL.X_UU", ["x_uu", "y_vv"]) == ["x_uu"]


def test_a_key_is_named_in_the_file_of_its_own_scenario_not_one_with_a_longer_name():
    """``scenarios.S10`` written inline in the experiment is not inside ``scenarios.S1`` (a file of its own)."""
    from marinebench.loading import _origin_of

    origins = {"": Path("exp.yaml"), "scenarios.S1": Path("s1.yaml")}
    assert _origin_of("scenarios.S10.dt", origins) == Path("exp.yaml")
    assert _origin_of("scenarios.S1.dt", origins) == Path("s1.yaml")
    assert _origin_of("scenarios.S1", origins) == Path("s1.yaml")


def test_the_allowed_keys_are_shown_up_to_twelve_by_default():
    twelve = [f"k{i:02d}" for i in range(12)]
    assert unknown_key_hint("zzz", twelve) == f" (allowed here: {', '.join(twelve)})"
    assert unknown_key_hint("zzz", twelve + ["k12"]) == f" (allowed here: {', '.join(twelve)}, …)"


def test_near_misses_are_at_least_60_percent_alike_and_at_most_three():
    assert near_misses("abc", ["abcxxxx", "abxxx"]) == ["abcxxxx"]  # similarity 0.6 is in, 0.5 is out
    assert near_misses("gain", ["gain1", "gain2", "gain3", "gain4"]) == ["gain1", "gain2", "gain3"]


def test_keys_further_down_keep_the_parent_and_are_at_most_three():
    deeper = ["a.horizon", "b.horizon", "c.horizon", "d.horizon"]
    assert unknown_key_hint("scenario.horizon", deeper) == (
        " (did you mean scenario.a.horizon, scenario.b.horizon or scenario.c.horizon?)")
    assert nested_keys([_Root], "horizon", depth=4) == ["side.horizon", "b_mid.leaf.horizon", "deep.mid.leaf.horizon"]


class _Left(BaseModel):
    model_config = ConfigDict(extra="forbid")
    kind: Literal["left"] = "left"
    size: float = 1.0


class _Right(BaseModel):
    model_config = ConfigDict(extra="forbid")
    kind: Literal["right"] = "right"
    width: float = 1.0


class _Pair(BaseModel):
    """Unions of two members: a discriminated one and a plain one."""
    side: _Left | _Right = Field(_Left(), discriminator="kind")
    scale: float | list[float] = 1.0


def test_a_two_member_unions_tag_or_member_type_is_dropped():
    err = first_error(_Pair, {"side": {"kind": "right", "width": "x"}})
    assert err["loc"] == ("side", "right", "width")
    assert key_path(_Pair, err["loc"])[0] == "side.width"
    err = first_error(_Pair, {"side": {"kind": "right", "bogus": 1}})
    assert key_path(_Pair, err["loc"], unknown=True) == ("side.bogus", ["kind", "width"])  # the member's keys
    err = first_error(_Pair, {"scale": "x"})
    assert len(err["loc"]) == 2  # ('scale', 'float') or ('scale', 'list[float]')
    assert key_path(_Pair, err["loc"])[0] == "scale"
