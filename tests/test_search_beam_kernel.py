"""The JAX beam kernel against its slow NumPy reference (same noise, same documented rules)."""
import dataclasses

import jax
import numpy as np
import pandas as pd
import pytest

from convsynth_jax.annotate.types import HP, LR, PC, FrameAudio
from convsynth_jax.graph.types import MotionGraph
from convsynth_jax.search.beam import beam_search, kept_edges
from convsynth_jax.search.check import check_path
from convsynth_jax.search.constraints import build_constraints
from convsynth_jax.search.params import SearchParams
from convsynth_jax.testing.search_reference import reference_beam_search

FPS = 10.0


def hub_graph(rng, n_clips=5, frames=50):
    """Clips of random PC / LR / idle runs (partner: random HP runs); original chains, a few hub states
    with many synthetic edges and the rest with 0-3, so path degrees vary a lot."""
    own, par, clip, frame, start, end, peak, pstart, pend = ([] for _ in range(9))
    for c in range(n_clips):
        lab = np.zeros(frames, np.int8)
        st, en, pk = (np.full(frames, -1, np.int32) for _ in range(3))
        f = int(rng.integers(2, 8))
        while f < frames - 6:
            n = int(rng.integers(4, 12))
            kind = int(rng.choice([PC, PC, LR]))
            e = min(f + n, frames)
            lab[f:e] = kind
            st[f:e], en[f:e] = f, e
            if kind == PC:
                pk[f:e] = f + int(rng.integers(0, e - f))
            f = e + int(rng.integers(2, 8))
        p = np.zeros(frames, np.int8)
        for _ in range(2):
            a = int(rng.integers(0, frames - 5)); p[a:a + int(rng.integers(2, 5))] = HP
        pst, pen = (np.full(frames, -1, np.int32) for _ in range(2))
        d = np.flatnonzero(np.diff(np.concatenate([[0], (p == HP).astype(np.int8), [0]])))
        for a, b in zip(d[::2], d[1::2]):
            pst[a:b], pen[a:b] = a, b
        own.append(lab); par.append(p); clip.append(np.full(frames, c)); frame.append(np.arange(frames))
        start.append(st); end.append(en); peak.append(pk); pstart.append(pst); pend.append(pen)
    S = n_clips * frames
    rows, cols, cost, syn = [], [], [], []
    hubs = set(rng.choice(S, S // 10, replace=False).tolist())
    for s in range(S):
        if (s + 1) % frames:
            rows.append(s); cols.append(s + 1); cost.append(0.0); syn.append(False)
        else:
            rows.append(s); cols.append(s - frames + 1); cost.append(4.0); syn.append(True)
        k = int(rng.integers(15, 40)) if s in hubs else int(rng.integers(0, 4))
        for t in rng.choice(S, k, replace=False):
            if t != s + 1:
                rows.append(s); cols.append(int(t)); cost.append(float(rng.uniform(0.5, 10))); syn.append(True)
    rows, cols, cost, syn = map(np.asarray, (rows, cols, cost, syn))
    o = np.argsort(rows, kind="stable")
    rows, cols, cost, syn = rows[o], cols[o], cost[o], syn[o]
    indptr = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=S))])
    cat = lambda x: np.concatenate(x).astype(np.int32)  # noqa: E731
    g = MotionGraph(tuple(f"c{c}" for c in range(n_clips)), FPS, cat(clip), cat(frame), cat(own), cat(start),
                    cat(end), cat(peak), cat(par), cat(pstart), cat(pend), np.ones(S, bool), indptr, cols,
                    cost.astype(np.float32), syn, {})
    audio = {f"c{c}": (FrameAudio(own[c], start[c], end[c], peak[c]),
                       FrameAudio(par[c], pstart[c], pend[c], np.full(frames, -1, np.int32))) for c in range(n_clips)}
    return g, audio


def input_from_clip(audio, name, T):
    """Constraints copied from one database clip: its PC / LR runs and its partner's HP runs."""
    own_fa, par_fa = audio[name]
    rows = []
    lab = own_fa.label[:T]
    d = np.flatnonzero(np.diff(np.concatenate([[0], lab, [0]])))
    for a, b in zip(d[:-1], d[1:]):
        if a < T and lab[a] in (PC, LR):
            kind = "PC" if lab[a] == PC else "LR"
            p = own_fa.seg_peak[a] / FPS if kind == "PC" else np.nan
            rows.append((kind, a / FPS, p, b / FPS))
    own = pd.DataFrame(rows, columns=["kind", "start", "peak", "end"]).drop_duplicates()
    plab = par_fa.label[:T]
    d = np.flatnonzero(np.diff(np.concatenate([[0], (plab == HP).astype(np.int8), [0]])))
    par = pd.DataFrame([("HP", a / FPS, np.nan, b / FPS) for a, b in zip(d[::2], d[1::2])],
                       columns=["kind", "start", "peak", "end"])
    return own, par


_REFERENCE_LOOKAHEAD: dict = {}


def _reference_lookahead(seed, matching, g, cons):
    """The slow look-ahead of the window that test_kernel_equals_reference builds for (seed, matching),
    computed once: it depends on the graph, the constraints and max_degree (24 in every case), not on
    the beam's sizes or temperature."""
    from convsynth_jax.testing.search_reference import reference_feasibility

    import hashlib
    import pickle

    key = (seed, matching, hashlib.sha256(pickle.dumps(cons)).hexdigest())   # the very same constraints
    if key not in _REFERENCE_LOOKAHEAD:
        _REFERENCE_LOOKAHEAD[key] = reference_feasibility(g, cons, 24)
    return _REFERENCE_LOOKAHEAD[key]


@pytest.mark.parametrize("matching", ["paper", "labels"])
@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("beam,max_candidates", [(32, 4096), (32, 48), (8, 8)])
@pytest.mark.parametrize("temperature", [0.05, 1.0])
def test_kernel_equals_reference(seed, beam, max_candidates, temperature, matching):
    rng = np.random.default_rng(seed)
    g, audio = hub_graph(rng)
    own, par = input_from_clip(audio, f"c{seed % 5}", 40)
    cfg = SearchParams(tolerance=0.1, beam_size=beam, max_candidates=max_candidates, max_degree=24,
                      temperature=temperature, retry_temperatures=[], retry_beam_size=0, matching=matching)
    cons = build_constraints(own, par, 40, FPS, cfg)
    ref = reference_beam_search(g, cons, cfg, seed=seed, temperature=temperature,
                                feas=_reference_lookahead(seed, matching, g, cons))
    res = beam_search(g, cons, cfg, seed=seed)
    assert res.success == ref.success
    if ref.success:
        np.testing.assert_array_equal(res.path, ref.path)
        assert res.cost == pytest.approx(ref.cost, rel=1e-5, abs=1e-4)
        rep = check_path([g.clip_names[g.clip[s]] for s in res.path], [int(g.frame[s]) for s in res.path],
                         audio, own, par, FPS, 0.1, matching=matching)
        assert rep["met"] == rep["total"], rep
    else:
        assert res.failed_frame == ref.failed_frame
    if max_candidates < beam * 24:
        # the budget really dropped edges in these cases, so the truncation rule was exercised
        assert ref.truncated_frames > 0


def test_no_duplicate_states_in_the_beam_and_impossible_input_fails_at_the_same_frame():
    rng = np.random.default_rng(7)
    g, audio = hub_graph(rng)
    own = pd.DataFrame([("LR", 1.0, np.nan, 1.6)], columns=["kind", "start", "peak", "end"])
    cfg = SearchParams(beam_size=16, max_candidates=64, retry_temperatures=[], retry_beam_size=0)
    # no state is an HP on its own channel, so requiring one is impossible
    cons = build_constraints(own, None, 30, FPS, cfg)
    cons.own_req[12:15] = HP
    ref = reference_beam_search(g, cons, cfg, seed=1)
    res = beam_search(g, cons, cfg, seed=1)
    assert not ref.success and not res.success and ref.failed_frame == res.failed_frame == 12


def test_kept_edges_are_each_states_cheapest_edges_in_order():
    """The kernels' flat edge layout (beam.kept_edges) against a plain per-state sort: each state's
    at most D cheapest out-edges, ties in CSR order, state after state."""
    g, _ = hub_graph(np.random.default_rng(3))
    first, kdeg, tgt, fcost, fsyn, D = kept_edges(g, 6)
    assert D == min(6, int(np.diff(g.indptr).max()))
    assert tgt.size == kdeg.sum() and (first == np.cumsum(kdeg) - kdeg).all()
    for s in range(g.num_states):
        t, c, y = g.out_edges(s)
        o = sorted(range(len(t)), key=lambda k: (c[k], k))[:6]
        e = slice(first[s], first[s] + kdeg[s])
        assert kdeg[s] == len(o)
        np.testing.assert_array_equal(tgt[e], t[o])
        np.testing.assert_array_equal(fcost[e], c[o])
        np.testing.assert_array_equal(fsyn[e], y[o])


def test_host_prng_key_is_jax_prng_key():
    """beam.prng_key builds the search's key on the host; it must be jax.random.PRNGKey's."""
    import jax

    from convsynth_jax.search.beam import prng_key

    for seed in (0, 1, 12345, 2 ** 31 - 1, 2 ** 31 - 1 + 5000, 2 ** 32 - 1):
        np.testing.assert_array_equal(np.asarray(prng_key(seed)), np.asarray(jax.random.PRNGKey(seed)))


def test_bad_labels_and_settings_are_reported():
    from convsynth_jax.errors import ConfigError, LabelError

    g, _ = hub_graph(np.random.default_rng(5))
    cons = build_constraints(pd.DataFrame(columns=["kind", "start", "peak", "end"]), None, 20, FPS, SearchParams())
    with pytest.raises(ConfigError, match="max_candidates"):
        beam_search(g, cons, SearchParams(max_candidates=0))
    g.own_label[7] = 99
    with pytest.raises(LabelError, match="graph state 7 .*clip c0, frame 7"):
        beam_search(g, cons, SearchParams())


def test_reported_synthetic_transitions_match_the_path():
    from convsynth_jax.search.dfs import stochastic_greedy_search
    from convsynth_jax.search.result import path_stats

    g, audio = hub_graph(np.random.default_rng(2))
    own, par = input_from_clip(audio, "c1", 40)
    own[["start", "peak", "end"]] += 0.7  # shifted, so playing clip c1 straight does not fit
    par[["start", "peak", "end"]] += 0.7
    cfg = SearchParams(beam_size=32, retry_temperatures=[1.0])
    cons = build_constraints(own, par, 40, FPS, cfg)
    for res in (beam_search(g, cons, cfg, seed=0), stochastic_greedy_search(g, cons, cfg, seed=0)):
        assert res.success
        # independently: a transition is synthetic when it is not the next frame of the same clip
        jumps = [t for t in range(1, 40) if not (g.clip[res.path[t]] == g.clip[res.path[t - 1]]
                                                 and g.frame[res.path[t]] == g.frame[res.path[t - 1]] + 1)]
        assert res.synthetic_at == jumps and res.num_synthetic_transitions == len(jumps) > 0
        total, costs, at = path_stats(g, res.path)
        assert at == jumps and res.cost == pytest.approx(total, rel=1e-6)


def test_wide_retry_finds_what_a_narrow_beam_misses():
    """search.retry_beam_size: when every ordinary attempt dies, one more attempt per temperature with a
    wider beam; its path satisfies the paper checker."""
    g, audio = hub_graph(np.random.default_rng(1))
    own, par = input_from_clip(audio, "c1", 40)
    narrow = SearchParams(beam_size=8, max_candidates=8, max_degree=24, retry_temperatures=[], retry_beam_size=0,
                          lookahead=False)
    cons = build_constraints(own, par, 40, FPS, narrow)
    assert not beam_search(g, cons, narrow, seed=1).success
    wide = SearchParams(beam_size=8, max_candidates=8, max_degree=24, retry_temperatures=[], retry_beam_size=64,
                        retry_max_candidates=1024, lookahead=False)
    res = beam_search(g, cons, wide, seed=1)
    assert res.success
    rep = check_path([g.clip_names[g.clip[s]] for s in res.path], [int(g.frame[s]) for s in res.path], audio, own,
                     par, FPS, 0.1)
    assert rep["met"] == rep["total"] and any(d["kind"] in ("PC", "LR") for d in rep["details"])


@pytest.mark.parametrize("matching", ["paper", "labels"])
def test_lookahead_solves_with_a_narrow_beam_what_it_misses_without(matching):
    """search.lookahead (default): the same narrow beam, one attempt, no retries, succeeds on the window
    where it dies without the look-ahead (it cannot see that its paths must wait for a clause start);
    the path passes the independent checker."""
    g, audio = hub_graph(np.random.default_rng(1))
    own, par = input_from_clip(audio, "c1", 40)
    narrow = SearchParams(beam_size=8, max_candidates=8, max_degree=24, retry_temperatures=[], retry_beam_size=0,
                          matching=matching)
    cons = build_constraints(own, par, 40, FPS, narrow)
    if matching == "paper":
        assert not beam_search(g, cons, dataclasses.replace(narrow, lookahead=False), seed=1).success
    res = beam_search(g, cons, narrow, seed=1)
    assert res.success
    rep = check_path([g.clip_names[g.clip[s]] for s in res.path], [int(g.frame[s]) for s in res.path], audio, own,
                     par, FPS, 0.1, matching=matching)
    assert rep["met"] == rep["total"] and any(d["kind"] in ("PC", "LR") for d in rep["details"])


@pytest.mark.parametrize("matching", ["paper", "labels"])
@pytest.mark.parametrize("seed", range(3))
def test_lookahead_kernel_equals_reference(seed, matching):
    """The JAX look-ahead (feasible._feasible_kernel) against the slow one (Python sets, one edge at a
    time): the same completable (state, flags) bits at every frame, on windows copied from the database
    and on ones shifted so that some are unsolvable."""
    from convsynth_jax.search.beam import _prepare, lookahead
    from convsynth_jax.testing.search_reference import reference_feasibility

    rng = np.random.default_rng(seed)
    g, audio = hub_graph(rng)
    own, par = input_from_clip(audio, f"c{seed % 5}", 30)
    if seed == 2:   # shifted by 0.3 s: the copied clause lengths no longer fit every placement
        own = own.assign(start=own.start + 0.3, end=own.end + 0.3, peak=own.peak + 0.3)
    cfg = SearchParams(max_degree=24, matching=matching)
    cons = build_constraints(own, par, 30, FPS, cfg)
    feas, ok = lookahead(g, cons, 24)
    got = np.asarray(feas)[:30, :g.num_states]
    ref = reference_feasibility(g, cons, 24)
    np.testing.assert_array_equal(got, ref)
    prep = _prepare(g, 24)
    codes = None if cons.paper is None else (cons.paper.own_codes, cons.paper.par_codes)
    e = prep.lookahead_edges(codes)

    def listed(edges):   # real (non-padding) entries of the dense rows
        return sum(int((np.asarray(t) < g.num_states).sum()) for t in edges.tgt)

    n_flat = listed(e)
    assert np.asarray(e.has_next)[:g.num_states].any() and n_flat > 0   # both the shift and the rows
    assert (np.asarray(e.entry) < g.num_states).any()                    # entry states get the full rule
    if codes is not None:   # the static contiguity rule dropped some synthetic edges
        assert n_flat < listed(prep.lookahead_edges(None))
    assert not got[:-1].all()                     # the windows constrain something
    if matching == "labels" and seed != 2:
        assert ok                                 # the clip the input was copied from is a path


@pytest.mark.parametrize("matching", ["paper", "labels"])
@pytest.mark.parametrize("seed", range(3))
def test_lookahead_and_beam_in_one_kernel_equal_the_two_kernels(seed, matching):
    """beam._lookahead_beam_kernel (the look-ahead and the first pruned attempt in one program) gives the
    same look-ahead bits, solvability and path as feasible's kernel followed by the beam kernel."""
    from convsynth_jax.search.beam import _beam_search_once, lookahead

    rng = np.random.default_rng(seed)
    g, audio = hub_graph(rng)
    own, par = input_from_clip(audio, f"c{seed % 5}", 30)
    if seed == 2:   # shifted: some placements no longer fit (unsolvable in paper mode)
        own = own.assign(start=own.start + 0.3, end=own.end + 0.3, peak=own.peak + 0.3)
    cfg = SearchParams(beam_size=16, max_candidates=64, max_degree=24, matching=matching)
    cons = build_constraints(own, par, 30, FPS, cfg)
    feas, ok = lookahead(g, cons, 24)
    want = _beam_search_once(g, cons, cfg, seed, 0.05, feas)
    got, feas2, ok2 = _beam_search_once(g, cons, cfg, seed, 0.05, lookahead=True)
    np.testing.assert_array_equal(np.asarray(feas2), np.asarray(feas))
    assert ok2 == ok and got.success == want.success and got.failed_frame == want.failed_frame
    if want.success:
        np.testing.assert_array_equal(got.path, want.path)
        assert got.cost == want.cost


def test_edge_or_is_a_bitwise_or_over_each_states_edges():
    """The look-ahead's OR over a state's listed edges (feasible.edge_or over the dense rows of
    feasible.edge_rows) against np.bitwise_or.at: flag sets that are not nested (own entry flag only
    0b1010, partner flag only 0b1100: 0b1110; a segment_max over the bytes, used before, gave 0b1100),
    random bytes of 4 and 2 bits, states with 1 to 300 edges (every row width, more than the 255 the
    byte-lane sum used before allowed) and rows padded to more than needed."""
    import jax.numpy as jnp

    from convsynth_jax.search.feasible import LookaheadEdges, edge_or, edge_rows, pad_lookahead, row_widths

    S = 400
    pad = S - 1
    A = np.zeros(S, np.uint8)
    A[1], A[2] = 0b1010, 0b1100
    src, tgt = [0, 0], [1, 2]
    A[3] = 0b1111
    src += [4] * 300; tgt += [3] * 300
    rng = np.random.default_rng(0)
    A[10:pad] = rng.integers(0, 16, pad - 10)
    extra_src = np.sort(rng.integers(5, pad, 2000)); extra_tgt = rng.integers(0, pad, 2000)
    src = np.concatenate([src, extra_src]).astype(np.int32); tgt = np.concatenate([tgt, extra_tgt]).astype(np.int32)
    widths = row_widths(300)
    assert widths == (4, 8, 16, 32, 64, 128, 256, 512)
    jitted_edge_or = jax.jit(edge_or, static_argnums=3)   # as inside the look-ahead kernel; one program, not op by op
    for F in (4, 2):
        a = A & np.uint8((1 << F) - 1)
        want = np.zeros(S, np.uint8)
        np.bitwise_or.at(want, src, a[tgt])
        s_rows, t_rows = edge_rows(src, tgt, pad, widths)
        padded = pad_lookahead(LookaheadEdges(np.zeros(S, bool), s_rows, t_rows, np.zeros(0, np.int32)),
                               (300,) * len(widths), 0)
        assert all(x.shape[0] >= 300 for x in padded.src) and all(x.shape[0] >= 300 for x in padded.tgt)
        for s_rows, t_rows in ((s_rows, t_rows), (padded.src, padded.tgt)):
            assert sum(int((t < pad).sum()) for t in t_rows) == src.size      # every edge listed once
            got = np.asarray(jitted_edge_or(jnp.asarray(a), tuple(map(jnp.asarray, s_rows)),
                                            tuple(map(jnp.asarray, t_rows)), S))
            np.testing.assert_array_equal(got, want)
        if F == 4:
            assert got[0] == 0b1110 and got[4] == 0b1111
    with pytest.raises(ValueError, match="widest row"):
        edge_rows(src, tgt, pad, row_widths(64))


@pytest.mark.parametrize("matching", ["paper", "labels"])
def test_shared_shapes_give_the_same_searches(monkeypatch, matching):
    """share_shapes pads two graphs' kernel arrays to one shape (one compiled program per conversation);
    the searches on both are the unshared ones exactly. Small buckets so the two graphs' own shapes differ."""
    from convsynth_jax.search import beam, feasible

    for mod, name, v in ((beam, "STATE_BUCKET", 64), (beam, "EDGE_BUCKET", 64), (feasible, "ROW_BUCKET", 8),
                         (feasible, "ENTRY_BUCKET", 16)):
        monkeypatch.setattr(mod, name, v)
    monkeypatch.setattr(beam, "_CACHE", [])
    graphs = [hub_graph(np.random.default_rng(1), n_clips=5), hub_graph(np.random.default_rng(2), n_clips=8)]
    cfg = SearchParams(beam_size=16, max_candidates=64, max_degree=24, matching=matching)

    def run():
        out = []
        for k, (g, audio) in enumerate(graphs):
            own, par = input_from_clip(audio, "c1", 40)
            cons = build_constraints(own, par, 40, FPS, cfg)
            res = beam_search(g, cons, cfg, seed=7 + k)
            prep = beam._prepare(g, 24)
            codes = None if cons.paper is None else (cons.paper.own_codes, cons.paper.par_codes)
            e = prep.lookahead_edges(codes)
            shapes = ([np.shape(x) for x in prep.device] + [np.shape(x) for x in prep.paper_device]
                      + [np.shape(x) for x in jax.tree.leaves(e)] + [prep.kernel_degree])
            out.append((res.success, None if res.path is None else list(res.path), res.cost, shapes))
        return out

    alone = run()
    assert alone[0][3] != alone[1][3]                       # on their own the two graphs' arrays differ
    monkeypatch.setattr(beam, "_CACHE", [])
    beam.share_shapes([g for g, _ in graphs], 24)
    shared = run()
    assert shared[0][3] == shared[1][3]                     # shared: one shape for both
    assert all(s[0] for s in shared)
    for a, s in zip(alone, shared):
        assert a[:3] == s[:3]                               # the same searches


@pytest.mark.parametrize("matching", ["paper", "labels"])
def test_same_rule_marks_frames_whose_arrival_rule_repeats(matching):
    """feasible.same_rule (the look-ahead skips a frame whose rule repeats once its bits settle) against a
    frame-by-frame comparison of the padded inputs: equal inputs at u and u + 1, and for ``paper`` no
    entry window open at u; never at the last frame."""
    from convsynth_jax.search.beam_kernel import padded_inputs
    from convsynth_jax.search.feasible import same_rule

    g, audio = hub_graph(np.random.default_rng(0))
    own, par = input_from_clip(audio, "c0", 30)
    cons = build_constraints(own, par, 30, FPS, SearchParams(max_degree=24, matching=matching))
    reqs, pw, reset, check, paper = padded_inputs(cons)
    fields = [*reqs, pw, reset, check] + ([*paper.own, *paper.partner] if paper is not None else [])
    Tp = pw.shape[0]
    want = np.zeros(Tp, bool)
    for u in range(Tp - 1):
        want[u] = all(np.asarray(a)[u] == np.asarray(a)[u + 1] for a in fields)
        if paper is not None:
            want[u] &= paper.own.kind[u] < 0 and paper.partner.kind[u] < 0
    got = np.asarray(same_rule(reqs, pw, reset, check, paper, paper is not None))
    np.testing.assert_array_equal(got, want)
    assert want.any() and not want.all()          # both kinds of frames occur in the window


@pytest.mark.parametrize("matching", ["paper", "labels"])
@pytest.mark.parametrize("seed", range(3))
def test_changed_state_lookahead_equals_the_dense_pass_and_the_reference(seed, matching):
    """The changed-state look-ahead (feasible._feasible_kernel with SparseEdges) gives the dense pass's
    bits and solvability bit for bit, and the slow reference's, on windows copied from the database (PC,
    LR, partner HP and idle frames) and shifted ones (seed 2: some placements no longer fit): with
    buffers so small (2 in-edge entries) that frames overflow into the dense pass, with chunks of 4
    entries (many chunks per frame) and with one chunk that holds every frame's changes."""
    from convsynth_jax.search.beam import _prepare
    from convsynth_jax.search.beam_kernel import padded_inputs
    from convsynth_jax.search.feasible import SparseCapacity, feasibility

    g, audio = hub_graph(np.random.default_rng(seed))
    own, par = input_from_clip(audio, f"c{(seed + 1) % 5}", 30)
    if seed == 2:
        own = own.assign(start=own.start + 0.3, end=own.end + 0.3, peak=own.peak + 0.3)
    cons = build_constraints(own, par, 30, FPS, SearchParams(max_degree=24, matching=matching))
    prep, inp = _prepare(g, 24), padded_inputs(cons)
    dense, ok_dense, (dkinds, dchg) = feasibility(prep, cons, inp, None, stats=True)
    np.testing.assert_array_equal(np.asarray(dense)[:30, :g.num_states], _reference_lookahead(seed, matching, g, cons))
    kinds_seen = set()
    for cap in (SparseCapacity(2, 1), SparseCapacity(2048, 4), SparseCapacity(2048, 2048)):
        got, ok, (kinds, nchg) = feasibility(prep, cons, inp, cap, stats=True)
        np.testing.assert_array_equal(np.asarray(got), np.asarray(dense))
        assert bool(ok) == bool(ok_dense)
        real = np.asarray(kinds) >= 0
        np.testing.assert_array_equal(np.asarray(kinds) < 0, np.asarray(dkinds) < 0)   # the same padding frames
        np.testing.assert_array_equal(np.asarray(nchg)[real], np.asarray(dchg)[real])  # the same changes per frame
        kinds_seen |= set(np.asarray(kinds)[real].tolist())
        if cap.sources == 2:   # a frame following more than 2 in-edge entries takes the dense pass
            assert np.asarray(nchg)[np.asarray(kinds) == 1].max(initial=0) <= 2
    assert {0, 1} <= kinds_seen          # both the dense pass and the changed states ran
    assert (np.asarray(dchg)[real] > 2).any()    # so the smallest buffers overflowed into the dense pass


def test_edge_lane_counts_count_each_flag_bit_over_each_states_edges():
    """feasible.edge_lane_counts (the changed-state look-ahead's per-state edge counts, one byte lane per
    flag bit) against np.add.at over the flat edges, on the dense rows of feasible.edge_rows; and
    byte_lanes against a bit-by-bit loop."""
    import jax.numpy as jnp

    from convsynth_jax.search.feasible import byte_lanes, edge_lane_counts, edge_rows, row_widths

    lanes = byte_lanes(4)
    for a in range(16):
        assert lanes[a] == sum(((a >> f) & 1) << (8 * f) for f in range(4))
    rng = np.random.default_rng(0)
    S = 300
    pad = S - 1
    src = np.sort(rng.integers(0, pad, 3000)).astype(np.int32)
    tgt = rng.integers(0, pad, 3000).astype(np.int32)
    A = rng.integers(0, 16, S).astype(np.uint8)
    A[pad] = 0
    want = np.zeros((S, 4), np.int64)
    for f in range(4):
        np.add.at(want[:, f], src, (A[tgt] >> f) & 1)
    s_rows, t_rows = edge_rows(src, tgt, pad, row_widths(int(np.bincount(src).max())))
    got = np.asarray(jax.jit(edge_lane_counts, static_argnums=3)(jnp.asarray(lanes)[A], s_rows, t_rows, S))
    for f in range(4):
        np.testing.assert_array_equal((got >> (8 * f)) & 255, want[:, f])


@pytest.mark.parametrize("matching", ["paper", "labels"])
def test_lookahead_pass_option_gives_the_same_searches(matching):
    """search.lookahead_pass: the changed-state and the dense look-ahead give the same search (path, cost,
    solvability) through beam_search and beam.lookahead; an unknown pass is a ConfigError naming the
    setting."""
    from convsynth_jax.errors import ConfigError
    from convsynth_jax.search.beam import lookahead

    g, audio = hub_graph(np.random.default_rng(3))
    own, par = input_from_clip(audio, "c2", 40)
    out = {}
    for mode in ("dense", "changed", "auto"):
        cfg = SearchParams(beam_size=16, max_candidates=64, max_degree=24, matching=matching, lookahead_pass=mode)
        cons = build_constraints(own, par, 40, FPS, cfg)
        res = beam_search(g, cons, cfg, seed=5)
        feas, ok = lookahead(g, cons, 24, lookahead_pass=mode)
        out[mode] = (res.success, None if res.path is None else list(res.path), res.cost, np.asarray(feas), ok)
    for mode in ("changed", "auto"):
        assert out[mode][:3] == out["dense"][:3] and out[mode][4] == out["dense"][4]
        np.testing.assert_array_equal(out[mode][3], out["dense"][3])
    cfg = SearchParams(max_degree=24, matching=matching, lookahead_pass="sparse")
    with pytest.raises(ConfigError, match="search.lookahead_pass"):
        beam_search(g, build_constraints(own, par, 40, FPS, cfg), cfg)
