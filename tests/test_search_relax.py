"""Best effort when no path meets every constraint (search/relax.py, ours): the greedy walk in runs
against the one-at-a-time walk, claims against the independent checker, determinism, the switch."""
import dataclasses

import numpy as np
import pandas as pd
import pytest

from convsynth_jax.config import default_params
from convsynth_jax.errors import ConfigError
from convsynth_jax.search.beam import beam_search, lookahead
from convsynth_jax.search.check import check_path, clip_audio_of_graph
from convsynth_jax.search.constraints import build_constraints, constraint_key
from convsynth_jax.search.dfs import stochastic_greedy_search
from convsynth_jax.search.params import SearchParams
from convsynth_jax.search.relax import best_effort_search, constraint_order, greedy_keep, path_meets

from test_search_beam_kernel import hub_graph, input_from_clip

FPS = 10.0
T = 40


def greedy_keep_reference(order, completable):
    """The obvious walk: one constraint at a time, kept when the kept ones plus it stay completable."""
    kept, dropped = [], []
    for k in order:
        (kept if completable(kept + [k]) else dropped).append(k)
    return kept, dropped


@pytest.mark.parametrize("seed", range(20))
def test_greedy_runs_keep_what_the_one_at_a_time_walk_keeps(seed):
    """On monotone predicates (random conflict pairs plus a size cap) the runs with bisection keep
    exactly the constraints of the one-at-a-time walk, with fewer oracle calls when few are dropped."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 30))
    order = list(range(n))
    pairs = {tuple(sorted(rng.choice(n, 2, replace=False))) for _ in range(int(rng.integers(0, 4)))} if n > 1 else set()
    cap = int(rng.integers(n // 2, n + 1))
    calls = []

    def completable(kept):
        calls.append(1)
        s = set(kept)
        return len(s) <= cap and not any(a in s and b in s for a, b in pairs)

    got = greedy_keep(order, completable)
    n_runs = len(calls)
    assert got == greedy_keep_reference(order, completable)
    if len(got[1]) <= 1 and n >= 16:
        assert n_runs < n


def _relax_input(audio, matching="paper"):
    """An input the window cannot meet as a whole: clip c0's first segments plus, for paper matching,
    a one-frame listener response (no source response is that short), for labels matching (which
    ignores one-frame segments but stitches runs) a 2 s partner hesitation (source ones last 0.2-0.4 s)."""
    own, par = input_from_clip(audio, "c0", T)
    own = own[own.end < 3.2]
    if matching == "paper":
        bad = pd.DataFrame([("LR", 3.4, np.nan, 3.5)], columns=["kind", "start", "peak", "end"])
        return pd.concat([own, bad], ignore_index=True), par
    return own, pd.DataFrame([("HP", 1.0, np.nan, 3.0)], columns=["kind", "start", "peak", "end"])


@pytest.mark.parametrize("method", ["beam", "dfs"])
@pytest.mark.parametrize("matching", ["paper", "labels"])
@pytest.mark.parametrize("seed", range(3))
def test_best_effort_claims_equal_the_checker_verdict(seed, matching, method):
    """Best effort on a window no path solves: a path comes back, the constraints it claims met and
    unmet are the independent checker's verdict (on the database annotation and on the one the graph
    stores), and every constraint the greedy kept is met."""
    rng = np.random.default_rng(seed)
    g, audio = hub_graph(rng)
    cfg = SearchParams(max_degree=24, beam_size=64, matching=matching, n_start=20, n_save=50,
                       on_failure="best_effort")
    search = beam_search if method == "beam" else stochastic_greedy_search
    own, par = _relax_input(audio, matching)
    full = build_constraints(own, par, T, FPS, cfg)
    assert not lookahead(g, full, 24)[1]                       # unsolvable as a whole
    assert not search(g, full, cfg, seed=seed).success          # the paper's behaviour: a failure
    res = best_effort_search(search, g, own, par, T, FPS, cfg, seed=seed)
    assert res.success and res.best_effort and res.relaxed
    assert ("LR", 34, 35) in res.relaxed or ("PH", 10, 30) in res.relaxed
    clips = [g.clip_names[g.clip[s]] for s in res.path]
    frames = [int(g.frame[s]) for s in res.path]
    for clip_audio in (audio, clip_audio_of_graph(g)):
        chk = check_path(clips, frames, clip_audio, own, par, FPS, 0.1, matching=matching)
        verdict = {constraint_key(d): bool(d["met"]) for d in chk["details"]}
        assert res.claimed == verdict
    kept = set(res.claimed) - set(res.relaxed)
    assert all(res.claimed[k] for k in kept)
    assert res.constraints_met == sum(verdict.values()) and res.constraints_total == len(verdict)


def test_best_effort_is_deterministic_and_keeps_the_heaviest_kinds_first():
    rng = np.random.default_rng(1)
    g, audio = hub_graph(rng)
    own, par = _relax_input(audio)
    cfg = SearchParams(max_degree=24, beam_size=64, on_failure="best_effort")
    a = best_effort_search(beam_search, g, own, par, T, FPS, cfg, seed=3)
    b = best_effort_search(beam_search, g, own, par, T, FPS, cfg, seed=3)
    np.testing.assert_array_equal(a.path, b.path)
    assert a.relaxed == b.relaxed and a.claimed == b.claimed
    # the relaxed window is solvable and the full one is not: every kept constraint holds on the path
    kept = build_constraints(own, par, T, FPS, cfg, relaxed=frozenset(a.relaxed))
    assert path_meets(g, kept, a.path)
    assert not path_meets(g, build_constraints(own, par, T, FPS, cfg), a.path)
    keys = [constraint_key(s) for s in build_constraints(own, par, T, FPS, cfg).segments]
    order = constraint_order(keys, cfg)
    w = [{"PC": 4, "LR": 2, "PH": 2, "idle": 1}[k[0]] for k in order]
    assert sorted(order) == sorted(keys) and w == sorted(w, reverse=True) and order[0][0] == "PC"
    # idle weighed above clauses: idle runs are tried first
    heavy_idle = dataclasses.replace(cfg, weight_idle=10.0)
    assert constraint_order(keys, heavy_idle)[0][0] == "idle"


def test_relaxing_frees_the_constraints_frames():
    own = pd.DataFrame([("PC", 0.5, 0.8, 1.5), ("LR", 2.0, np.nan, 2.4)], columns=["kind", "start", "peak", "end"])
    par = pd.DataFrame([("HP", 3.0, np.nan, 3.6)], columns=["kind", "start", "peak", "end"])
    for matching in ("paper", "labels"):
        cfg = SearchParams(matching=matching)
        full = build_constraints(own, par, 50, FPS, cfg)
        keys = {constraint_key(s) for s in full.segments}
        assert {("PC", 5, 15), ("LR", 20, 24), ("PH", 30, 36)} <= keys
        idle = next(k for k in keys if k[0] == "idle" and k[1] == 0)
        r = build_constraints(own, par, 50, FPS, cfg, relaxed={("PC", 5, 15), ("PH", 30, 36), idle})
        assert {constraint_key(s) for s in r.segments} == keys - {("PC", 5, 15), ("PH", 30, 36), idle}
        assert (r.own_req[:idle[2]] == -1).all() and (r.own_req[5:15] == -1).all() and (r.partner_req == -1).all()
        if matching == "paper":
            assert r.paper.own_free[:idle[2]].all() and (r.paper.own_kind[:15] == -1).all()
            assert (r.paper.par_kind == -1).all()


def test_on_failure_and_retime_defaults_are_the_paper():
    assert SearchParams().on_failure == "fail" and SearchParams().retime_factor == 0.0
    paper = default_params(["preset=paper"]).search
    assert paper == SearchParams()
    quality = default_params(["preset=quality"]).search
    assert quality.on_failure == "best_effort" and quality.retime_factor > 0
    assert quality.beam_size > SearchParams().beam_size and quality.max_candidates > SearchParams().max_candidates
    # nothing else of the search differs from the paper's
    assert dataclasses.replace(quality, on_failure="fail", retime_factor=0.0, beam_size=SearchParams().beam_size,
                               max_candidates=SearchParams().max_candidates) == SearchParams()


def test_bad_on_failure_and_retime_settings_are_config_errors():
    from convsynth_jax.search.relax import check_on_failure

    with pytest.raises(ConfigError, match="on_failure"):
        check_on_failure(SearchParams(on_failure="maybe"))
    with pytest.raises(ConfigError, match="weight_idle"):
        check_on_failure(SearchParams(weight_idle=-1.0))
    own = pd.DataFrame([("PC", 0.5, 0.8, 1.5)], columns=["kind", "start", "peak", "end"])
    with pytest.raises(ConfigError, match="retime_factor"):
        build_constraints(own, None, 20, FPS, SearchParams(retime_factor=1.5))
    with pytest.raises(ConfigError, match="matching=paper"):
        build_constraints(own, None, 20, FPS, SearchParams(matching="labels", retime_factor=0.2))


@pytest.mark.parametrize("method", ["beam", "dfs"])
def test_no_diagnostic_attempt_when_best_effort_takes_over(method, monkeypatch):
    """Under the paper's rule an unsolvable window is searched once more without the look-ahead, to name
    the frame where its paths die; under best effort that attempt would be discarded, so it is not made
    (on a long silent listener it cost more than the relaxation), and the best-effort path is the same."""
    from convsynth_jax.search import beam as beam_mod
    from convsynth_jax.search import dfs as dfs_mod

    g, audio = hub_graph(np.random.default_rng(0))
    own, par = _relax_input(audio)
    paper = SearchParams(max_degree=24, beam_size=64, n_start=20, n_save=50)
    quality = dataclasses.replace(paper, on_failure="best_effort")
    full = build_constraints(own, par, T, FPS, paper)
    calls = []
    if method == "beam":
        real = beam_mod._beam_search_once
        monkeypatch.setattr(beam_mod, "_beam_search_once", lambda *a, **k: calls.append(k.get("lookahead")) or real(*a, **k))
        search = beam_search
    else:
        real = dfs_mod.stochastic_greedy_search
        monkeypatch.setattr(dfs_mod, "stochastic_greedy_search", lambda *a, **k: calls.append(1) or real(*a, **k))
        search = stochastic_greedy_search
    res = search(g, full, paper, seed=2)
    assert not res.success and "look-ahead" in res.failure and len(calls) == (2 if method == "beam" else 1)
    calls.clear()
    res = search(g, full, quality, seed=2)
    assert not res.success and res.failure.startswith("look-ahead: no path")
    assert len(calls) == (1 if method == "beam" else 0)
    a = best_effort_search(search, g, own, par, T, FPS, quality, seed=3)
    b = best_effort_search(search, g, own, par, T, FPS, paper, seed=3)
    assert a.success and a.relaxed == b.relaxed
    np.testing.assert_array_equal(a.path, b.path)
