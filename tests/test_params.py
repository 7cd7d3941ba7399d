"""One typed-parameter path: every config group, task setting and the synthetic generator converts
to its frozen dataclass through convsynth_jax.schema.build_params, with errors that name the key."""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Dict, List, Optional

import pytest

from convsynth_jax.config import CONFIG_DIR, GROUPS, SCHEMA_GROUPS, TASKS, compose, group_params, run_task, task_settings, to_params
from convsynth_jax.errors import ConfigError
from convsynth_jax.schema import build_params

CONF = Path(CONFIG_DIR)
# config.yaml's groups that are files under conf/<group>/ (hydra: Hydra's own settings)
FILE_GROUPS = sorted(d.name for d in CONF.iterdir() if d.is_dir() and d.name != "hydra")


def _options(group: str) -> list[str]:
    return sorted(p.stem for p in (CONF / group).glob("*.yaml"))


@pytest.mark.parametrize("group", [g for g in FILE_GROUPS if g in GROUPS])
def test_every_option_of_every_group_converts(group):
    for option in _options(group):
        cfg = compose([f"{group}={option}"])
        p = group_params(cfg, group)
        assert dataclasses.is_dataclass(p) and not isinstance(p, type), (group, option)
        assert type(p).__dataclass_params__.frozen, (group, option)
        if group == "corpus" and p.kind == "synthetic":   # the generator's own typed parameters
            from convsynth_jax.data.synthetic.config import GeneratorParams, generator_params

            assert isinstance(generator_params(p.generator), GeneratorParams)


@pytest.mark.parametrize("group", ["preset", "experiment", "debug"])
def test_every_preset_experiment_and_debug_option_converts_the_whole_config(group):
    for option in _options(group):
        p = to_params(compose([f"{group}={option}"]))
        for g in GROUPS:
            assert dataclasses.is_dataclass(getattr(p, g)), (group, option, g)


def test_every_task_has_typed_settings():
    assert set(_options("task")) == set(TASKS)
    for name in TASKS:
        s = task_settings(compose([f"task={name}"]))
        assert dataclasses.is_dataclass(s) and type(s).__dataclass_params__.frozen and s.name == name


def test_the_whole_config_is_typed():
    p = to_params(compose(["corpus=synthetic_tiny"]))
    from convsynth_jax.cdbn.params import CDBNEvalParams, CDBNParams
    from convsynth_jax.kernel_cache import JaxCacheParams
    from convsynth_jax.walktalk.params import WalkTalkParams

    assert isinstance(p.cdbn, CDBNParams) and isinstance(p.cdbn.eval, CDBNEvalParams)
    assert isinstance(p.walktalk, WalkTalkParams) and isinstance(p.jax_cache, JaxCacheParams)
    assert p.cdbn.eval.jdbn_grid == (4, 7, 10) and p.cdbn.train.seed == p.seed   # lists -> tuples, ${seed} resolved
    assert p.jax_cache.dir.endswith("jax_cache") and p.loo.max_windows is None
    assert not hasattr(p, "extra")


@pytest.mark.parametrize("group", sorted(GROUPS))
def test_an_unknown_key_names_itself(group):
    cfg = compose([])
    with pytest.raises(ConfigError, match=rf"{group}\.no_such_key"):
        build_params(type(group_params(cfg, group)), {"no_such_key": 1}, group)


@pytest.mark.parametrize("override, key", [
    ("+cdbn.train.max_itr=3", "cdbn.train.max_itr"),
    ("+cdbn.eval.hands.wave=x", "cdbn.eval.hands.wave"),
    ("+walktalk.splice.cc=1.0", "walktalk.splice.cc"),
    ("+loo.windw=10", "loo.windw"),
    ("+jax_cache.dirs=x", "jax_cache.dirs"),
    ("+corpus.generator.posture_shift_Sd=3.0", "corpus.generator.posture_shift_Sd"),
    ("+corpus.generator.characters.main-agent.p_pc_lhh=0.5", "corpus.generator.characters.main-agent.p_pc_lhh"),
])
def test_an_unknown_key_in_a_config_is_a_clear_error(override, key):
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        to_params(compose([override]))


def test_an_unknown_task_key_fails_the_task_before_any_work(tmp_path):
    with pytest.raises(ConfigError, match=r"task\.paper_k\b"):
        run_task(compose(["+task.paper_k=[2]"]), tmp_path)
    assert not (tmp_path / "summary.json").exists()


@pytest.mark.parametrize("override, key", [
    ("loo.window=abc", "loo.window"),
    ("loo.max_windows=1.5", "loo.max_windows"),
    ("cdbn.jdbn_states=many", "cdbn.jdbn_states"),
    ("walktalk.splice.stylize_deictic=3", "walktalk.splice.stylize_deictic"),
    ("jax_cache.min_entry_size_bytes=big", "jax_cache.min_entry_size_bytes"),
    ("corpus.generator.num_sessions=two", "corpus.generator.num_sessions"),
])
def test_a_mistyped_value_names_its_key(override, key):
    with pytest.raises(ConfigError, match=key.replace(".", r"\.") + ": expected"):
        to_params(compose([override]))


def test_a_mistyped_task_setting_names_its_key():
    with pytest.raises(ConfigError, match=r"task\.paper_ks\[0\]: expected int"):
        task_settings(compose(["task.paper_ks=[a]"]))
    with pytest.raises(ConfigError, match=r"task\.export_bvh: expected bool"):
        task_settings(compose(["task=loo", "task.export_bvh=maybe"]))


def test_schema_groups_still_check_keys_when_the_config_is_composed():
    from hydra.errors import ConfigCompositionException

    assert set(SCHEMA_GROUPS) <= set(GROUPS)
    with pytest.raises(ConfigCompositionException):
        compose(["graph.no_such_key=1"])


@dataclasses.dataclass(frozen=True)
class _Inner:
    a: float = 1.0
    b: tuple = (1, 2)


@dataclasses.dataclass(frozen=True)
class _Named:
    x: int
    y: float = 0.5


@dataclasses.dataclass(frozen=True)
class _Outer:
    inner: _Inner = _Inner()
    n: Optional[int] = None
    names: List[str] = dataclasses.field(default_factory=list)
    by_role: Dict[str, _Named] = dataclasses.field(default_factory=lambda: {"a": _Named(1), "b": _Named(2, 0.25)})
    either: float | str = "auto"


def test_build_params_converts_checks_and_merges():
    o = build_params(_Outer, {"inner": {"a": 2, "b": [3, [4, 5]]}, "n": 3, "names": ["p"], "either": 1,
                              "by_role": {"b": {"y": 1}}}, "outer")
    assert o.inner == _Inner(2.0, (3, (4, 5))) and isinstance(o.inner.a, float)      # int -> float, lists -> tuples
    assert o.n == 3 and o.names == ["p"] and o.either == 1.0
    assert o.by_role == {"a": _Named(1), "b": _Named(2, 1.0)}   # a partial entry merges onto its default
    assert build_params(_Outer, {"inner": {"b": []}}).inner.a == 1.0    # partial nested dataclass keeps defaults
    assert build_params(_Outer, None) == _Outer()
    with pytest.raises(ConfigError, match=r"outer\.inner\.c"):
        build_params(_Outer, {"inner": {"c": 1}}, "outer")
    with pytest.raises(ConfigError, match=r"outer\.n: expected"):
        build_params(_Outer, {"n": True}, "outer")    # a bool is not an int
    with pytest.raises(ConfigError, match=r"outer\.by_role\.c: missing key outer\.by_role\.c\.x"):
        build_params(_Outer, {"by_role": {"c": {"y": 1.0}}}, "outer")
    with pytest.raises(ConfigError, match=r"outer\.names\[1\]: expected str"):
        build_params(_Outer, {"names": ["a", 2]}, "outer")
    with pytest.raises(ConfigError, match=r"outer: expected a mapping"):
        build_params(_Outer, [1], "outer")
