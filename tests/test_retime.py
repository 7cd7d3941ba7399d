"""Retiming (search.retime_factor, ours): the matching tolerance, the warp knots, the motion warp
against a slow per-frame reference, and a retimed clause realized at the input's times."""
import dataclasses

import numpy as np
import pandas as pd
import pytest

from convsynth_jax.annotate.types import PC, FrameAudio
from convsynth_jax.data.skeleton_seated import seated_skeleton
from convsynth_jax.graph.types import MotionGraph
from convsynth_jax.search.beam import beam_search
from convsynth_jax.search.check import check_path
from convsynth_jax.search.constraints import build_constraints
from convsynth_jax.search.params import SearchParams
from convsynth_jax.testing.search_reference import reference_beam_search
from convsynth_jax.skeleton import Motion
from convsynth_jax.synth.params import SynthParams
from convsynth_jax.synth.pipeline import synthesize_character
from convsynth_jax.synth.retime import warp_motion

FPS = 10.0


def _slerp_reference(q0, q1, a):
    """Slerp of two unit quaternions written out (one pair, Python floats)."""
    d = float(np.dot(q0, q1))
    if d < 0:
        q1, d = -q1, -d
    th = np.arccos(min(d, 1.0))
    if th < 1e-9:
        return q0
    return (np.sin((1 - a) * th) * q0 + np.sin(a * th) * q1) / np.sin(th)


def warp_reference(motion, out_knots, path_knots):
    """Per output frame: find the knot interval by a linear scan, the path time by the two-point line
    formula, then slerp each joint and lerp each translation between the two nearest frames."""
    T, J = motion.rotations.shape[:2]
    rot, tr = np.zeros((T, J, 4)), np.zeros((T, J, 3))
    for t in range(T):
        k = 0
        while not (out_knots[k] <= t <= out_knots[k + 1]):
            k += 1
        x0, x1, y0, y1 = out_knots[k], out_knots[k + 1], path_knots[k], path_knots[k + 1]
        tau = y0 + (t - x0) * (y1 - y0) / (x1 - x0)
        i = min(int(np.floor(tau)), T - 1)
        j = min(i + 1, T - 1)
        a = tau - i
        for jj in range(J):
            rot[t, jj] = _slerp_reference(motion.rotations[i, jj], motion.rotations[j, jj], a)
            tr[t, jj] = (1 - a) * motion.translations[i, jj] + a * motion.translations[j, jj]
    return rot, tr


def _random_motion(rng, T=60):
    skel = seated_skeleton()
    J = skel.num_joints
    q = rng.normal(size=(T, J, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    tr = rng.normal(size=(T, J, 3))
    return Motion(skel, q, tr, FPS, "random")


@pytest.mark.parametrize("seed", range(3))
def test_warp_equals_the_per_frame_reference(seed):
    rng = np.random.default_rng(seed)
    m = _random_motion(rng)
    out_k = np.array([0.0, 12, 25, 45, 59])
    path_k = np.array([0.0, 10, 20, 40, 59])
    w = warp_motion(m, out_k, path_k)
    rot, tr = warp_reference(m, out_k, path_k)
    np.testing.assert_allclose(np.abs(np.sum(w.rotations * rot, -1)), 1.0, atol=1e-9)
    np.testing.assert_allclose(w.translations, tr, atol=1e-9)
    # the knots show the path frames exactly
    for o, p in zip(out_k.astype(int), path_k.astype(int)):
        np.testing.assert_allclose(np.abs(np.sum(w.rotations[o] * m.rotations[p], -1)), 1.0, atol=1e-9)


def test_bad_warp_knots_are_config_errors():
    from convsynth_jax.errors import ConfigError

    m = _random_motion(np.random.default_rng(0), 20)
    with pytest.raises(ConfigError, match="increasing knots"):
        warp_motion(m, [0, 10, 5, 19], [0, 4, 8, 19])
    with pytest.raises(ConfigError, match="increasing knots"):
        warp_motion(m, [0, 10, 18], [0, 4, 18])


def _labelled_graph(own, clip, frame, st, en, pk, frames, jumps):
    """A graph over clips with the given per-frame own labels and segments: each frame's natural edge to
    the next (cost 0), and from every frame where ``jumps(clip, frame)`` synthetic edges (cost 1) to any
    clip's frames 0, 3 and 6; with each clip's FrameAudio (silent partner)."""
    n_clips = len(own)
    S = n_clips * frames
    rows, cols, cost, syn = [], [], [], []
    for c in range(n_clips):
        for f in range(frames):
            s = c * frames + f
            if f + 1 < frames:
                rows.append(s); cols.append(s + 1); cost.append(0.0); syn.append(False)
            if jumps(c, f):
                for c2 in range(n_clips):
                    for g in (0, 3, 6):
                        if c2 * frames + g != s + 1:
                            rows.append(s); cols.append(c2 * frames + g); cost.append(1.0); syn.append(True)
    rows, cols, cost, syn = map(np.asarray, (rows, cols, cost, syn))
    o = np.lexsort((cols, rows))
    rows, cols, cost, syn = rows[o], cols[o], cost[o], syn[o]
    indptr = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=S))])
    cat = lambda x: np.concatenate(x).astype(np.int32)  # noqa: E731
    z = np.zeros(S, np.int32)
    g = MotionGraph(tuple(f"c{c}" for c in range(n_clips)), FPS, cat(clip), cat(frame), cat(own), cat(st), cat(en),
                    cat(pk), z, z - 1, z - 1, np.ones(S, bool), indptr, cols, cost.astype(np.float32), syn, {})
    audio = {f"c{c}": (FrameAudio(own[c], st[c].astype(np.int32), en[c].astype(np.int32), pk[c].astype(np.int32)),
                       FrameAudio(np.zeros(frames, np.int8), *(np.full(frames, -1, np.int32),) * 3))
             for c in range(n_clips)}
    return g, audio


def clause_graph(length=20, frames=60, n_clips=3):
    """Clips with one PC [10, 10 + length) each (peak at its middle), chained, each clip's last frame
    linked back to every clip's first (synthetic), so a path can wait in idle frames."""
    own, clip, frame, st, en, pk = [], [], [], [], [], []
    for c in range(n_clips):
        lab = np.zeros(frames, np.int8)
        lab[10:10 + length] = PC
        on = lab > 0
        own.append(lab); clip.append(np.full(frames, c)); frame.append(np.arange(frames))
        st.append(np.where(on, 10, -1)); en.append(np.where(on, 10 + length, -1))
        pk.append(np.where(on, 10 + length // 2, -1))
    # idle frames before the clause (and each clip's last frame) jump to any clip's idle frames
    g, audio = _labelled_graph(own, clip, frame, st, en, pk, frames, lambda c, f: f < 10 or f == frames - 1)
    skel = seated_skeleton()
    J = skel.num_joints
    motions = {}
    for c in range(n_clips):   # joint 1 turns about x by 0.02 rad per frame: every frame's pose differs
        ang = 0.02 * np.arange(frames) + c
        rot = np.zeros((frames, J, 4)); rot[..., 0] = 1
        rot[:, 1, 0], rot[:, 1, 1] = np.cos(ang / 2), np.sin(ang / 2)
        tr = np.broadcast_to(skel.offsets, (frames, J, 3)).copy()
        motions[f"c{c}"] = Motion(skel, rot, tr, FPS, f"c{c}")
    return g, audio, motions


def test_retime_tolerance_admits_a_clause_up_to_the_factor_longer_or_shorter():
    own = pd.DataFrame([("PC", 1.0, 2.2, 3.5)], columns=["kind", "start", "peak", "end"])   # 25 frames
    c0 = build_constraints(own, None, 50, FPS, SearchParams())
    c2 = build_constraints(own, None, 50, FPS, SearchParams(retime_factor=0.2))
    w = c2.paper.own_kind >= 0
    assert (c0.paper.own_end_tol[w] == 1).all() and (c2.paper.own_end_tol[w] == 1 + 5).all()   # floor(0.2 * 25)
    assert (c2.paper.own_peak_tol[w] == 1 + 2).all()                                           # floor(0.2 * 12)
    # the label core and the idle rule leave the end slack free; no own hesitation may enter it
    assert (c2.own_req[11:34 - 5] == PC).all() and (c2.own_req[29:41] == -1).all() and c2.own_req[41] == 0
    assert (c2.own_not[29:41] == 3).all() and c2.own_not[28] == -1 and (c0.own_not == -1).all()
    assert [s for s in c2.segments if s["kind"] == "idle"] == [s for s in c0.segments if s["kind"] == "idle"]


@pytest.mark.parametrize("input_frames", [24, 17])
def test_a_retimed_clause_is_realized_at_the_input_times(input_frames):
    """Source clauses last 20 frames; the input clause 24 (or 17). Paper matching (tolerance 1 frame)
    finds no path; with retime_factor 0.2 the search matches a source clause, the realized motion shows
    its start, peak and end frames at the input's start, peak and end, and the checker confirms the
    clause through the warp (and refuses it without)."""
    g, audio, motions = clause_graph()
    s, e = 12, 12 + input_frames
    p = s + input_frames // 2
    own = pd.DataFrame([("PC", s / FPS, p / FPS, e / FPS)], columns=["kind", "start", "peak", "end"])
    T = 50
    base = SearchParams(tolerance=0.1, beam_size=64, max_degree=24)
    assert not beam_search(g, build_constraints(own, None, T, FPS, base), base).success
    cfg = dataclasses.replace(base, retime_factor=0.2)
    res = synthesize_character(g, motions, own, None, T, cfg, SynthParams(blend_frames=0), seed=0)
    assert res.success and not res.best_effort and res.warp is not None
    out_k, path_k = res.warp
    # the path plays one whole source clause [10, 30) of some clip starting within the tolerance of s
    k = [i for i, f in enumerate(res.source_frame) if f == 10 and g.own_label[res.path[i]] == PC][0]
    st, pk, en = k, k + 10, k + 20
    assert abs(st - s) <= 1
    plain = synthesize_character(g, motions, own, None, T, dataclasses.replace(cfg, retime_factor=0.0), SynthParams(
        blend_frames=0), seed=0)
    assert not plain.success
    tau = np.interp(np.arange(T), out_k, path_k)
    for o, q in ((s, st), (p, pk), (e, en)):
        assert abs(tau[o] - q) < 1.0                                    # the input time shows the source's
        ang = 2 * np.arctan2(res.motion.rotations[o, 1, 1], res.motion.rotations[o, 1, 0])
        src = motions[res.source_clip[q]]
        ang_src = 2 * np.arctan2(src.rotations[res.source_frame[q], 1, 1], src.rotations[res.source_frame[q], 1, 0])
        assert abs(ang - ang_src) <= 0.02 + 1e-9                         # within a frame of the source's pose
    chk = check_path(res.source_clip, res.source_frame, audio, own, None, FPS, 0.1, warp=res.warp)
    assert all(d["met"] for d in chk["details"]), chk
    assert res.constraints_met == res.constraints_total == chk["total"]
    raw = check_path(res.source_clip, res.source_frame, audio, own, None, FPS, 0.1)
    assert not all(d["met"] for d in raw["details"] if d["kind"] == "PC")


def test_retimed_kernel_equals_the_reference():
    """The beam kernel and its NumPy reference apply the same retimed placement rule."""
    g, audio, _ = clause_graph()
    own = pd.DataFrame([("PC", 1.2, 2.4, 3.6)], columns=["kind", "start", "peak", "end"])
    cfg = SearchParams(tolerance=0.1, beam_size=32, max_degree=24, retime_factor=0.2, retry_temperatures=[],
                       retry_beam_size=0, lookahead=False)
    cons = build_constraints(own, None, 50, FPS, cfg)
    ref = reference_beam_search(g, cons, cfg, seed=1, temperature=cfg.temperature)
    res = beam_search(g, cons, cfg, seed=1)
    assert res.success and ref.success
    np.testing.assert_array_equal(res.path, ref.path)


def test_spread_slow_stretches_drops_only_identity_knots_next_to_slow_pieces():
    from convsynth_jax.synth.retime import spread_slow_stretches

    out_k, path_k = [0, 20, 30, 49], [0, 24, 30, 49]      # (30 <- 30) returns to the identity: speed 0.6 before it
    o, q = spread_slow_stretches(out_k, path_k, 0.8)
    assert o.tolist() == [0, 20, 49] and q.tolist() == [0, 24, 49]          # the matched knot stays
    assert (np.diff(q) / np.diff(o)).min() >= 0.8
    o, q = spread_slow_stretches(out_k, path_k, 0.0)                          # off: unchanged
    assert o.tolist() == out_k and q.tolist() == path_k
    o, q = spread_slow_stretches([0, 20, 30, 49], [0, 16, 26, 49], 0.9)       # no identity knot: nothing to drop
    assert o.tolist() == [0, 20, 30, 49] and q.tolist() == [0, 16, 26, 49]


def test_retime_min_speed_spreads_the_slow_idle_stretch_and_keeps_the_clause():
    """An input clause of 17 frames answered by a 20-frame source clause: the warp returns to the
    identity a few idle frames after the clause, playing them at 0.71x; with synth.retime_min_speed
    0.9 that return is dropped, no piece of the warp is slower than 0.9 and the checker still confirms
    the clause through the warp."""
    g, audio, motions = clause_graph()
    s, e = 12, 29
    own = pd.DataFrame([("PC", s / FPS, (s + 8) / FPS, e / FPS)], columns=["kind", "start", "peak", "end"])
    cfg = SearchParams(tolerance=0.1, beam_size=64, max_degree=24, retime_factor=0.2)
    speeds = {}
    for ms in (0.0, 0.9):
        res = synthesize_character(g, motions, own, None, 50, cfg, SynthParams(blend_frames=0, retime_min_speed=ms),
                                   seed=0)
        assert res.success and res.constraints_met == res.constraints_total == 3
        chk = check_path(res.source_clip, res.source_frame, audio, own, None, FPS, 0.1, warp=res.warp)
        assert all(d["met"] for d in chk["details"])
        o, q = res.warp
        speeds[ms] = (np.diff(q) / np.diff(o)).min()
    assert speeds[0.0] < 0.75 and speeds[0.9] >= 0.9


def test_penalized_graph_adds_the_penalties_and_keeps_the_temperature_unit():
    from convsynth_jax.systems.motion_graph import penalized_graph

    g, _, _ = clause_graph()
    src = np.repeat(np.arange(g.num_states), np.diff(g.indptr))
    back = g.synthetic & (g.clip[src] == g.clip[g.indices]) & (g.frame[g.indices] < g.frame[src])
    assert back.any() and (g.synthetic & ~back).any()
    same, k = penalized_graph(g)
    assert same is g and k == 1.0
    gp, k = penalized_graph(g, transition_penalty=1.0, loop_penalty=2.0)   # median synthetic cost 1
    assert np.allclose(gp.cost[~g.synthetic], 0.0)
    assert np.allclose(gp.cost[g.synthetic & ~back], 2.0) and np.allclose(gp.cost[back], 4.0)
    assert k == pytest.approx(1.0 / np.median(gp.cost[g.synthetic]))
    assert np.array_equal(g.cost[g.synthetic], np.ones(int(g.synthetic.sum())))   # the graph itself unchanged


def test_loop_penalty_keeps_paths_from_replaying_their_clip():
    """A 100-frame window without constraints over 60-frame clips needs a synthetic transition; all of
    them cost the same, so without the penalty some paths jump back into the clip they are playing
    (a replay); with synth.loop_penalty 2 none does."""
    from convsynth_jax.search.beam import beam_search
    from convsynth_jax.systems.motion_graph import penalized_graph

    g, _, _ = clause_graph()
    loops = {}
    for lp in (0.0, 2.0):
        gp, k = penalized_graph(g, loop_penalty=lp)
        sp = SearchParams(use_constraints=False, beam_size=64, max_degree=24, temperature=0.5 * k)
        c = build_constraints(None, None, 100, FPS, sp)
        n = 0
        for seed in range(8):
            p = beam_search(gp, c, sp, seed=seed).path
            n += sum(int(g.clip[a] == g.clip[b] and g.frame[b] < g.frame[a]) for a, b in zip(p[:-1], p[1:]))
        loops[lp] = n
    assert loops[0.0] > 0 and loops[2.0] == 0


def _tremor_motion(frames=60):
    """Joint 1 turns slowly about x (0.004 rad per frame) with a tremor of +-0.01 rad each frame."""
    skel = seated_skeleton()
    J = skel.num_joints
    ang = 0.004 * np.arange(frames) + 0.01 * (-1.0) ** np.arange(frames)
    rot = np.zeros((frames, J, 4)); rot[..., 0] = 1
    rot[:, 1, 0], rot[:, 1, 1] = np.cos(ang / 2), np.sin(ang / 2)
    tr = np.broadcast_to(skel.offsets, (frames, J, 3)).copy()
    return Motion(skel, rot, tr, FPS, "tremor")


def _step_angles(m):
    ang = 2 * np.arctan2(m.rotations[:, 1, 1], m.rotations[:, 1, 0])
    return np.abs(np.diff(ang))


def test_retime_detail_keeps_the_frame_to_frame_motion_of_a_slowed_stretch():
    """Output frames 10-40 show path frames 10-25 (0.5x): interpolated, the tremor's steps shrink to
    a fraction of the source's; with synth.retime_detail_frames 3 they keep the source's size. Where
    the warp is the identity (frames 0-10) the motion is the source's, with or without the option."""
    m = _tremor_motion()
    out_k, path_k = [0, 10, 40, 59], [0, 10, 25, 59]
    src = _step_angles(m)[12:38].mean()
    plain = _step_angles(warp_motion(m, out_k, path_k))[12:38].mean()
    kept_m = warp_motion(m, out_k, path_k, detail_frames=3)
    kept = _step_angles(kept_m)[12:38].mean()
    assert plain < 0.6 * src and kept > 0.8 * src
    assert np.allclose(kept_m.rotations[:9], m.rotations[:9], atol=1e-9)
    ident = warp_motion(m, [0, 59], [0, 59], detail_frames=3)
    assert np.allclose(ident.rotations, m.rotations, atol=1e-9)


def test_detail_options_are_off_in_the_paper_preset_and_on_in_quality():
    from convsynth_jax.config import default_params

    paper, quality = default_params([]), default_params(["preset=quality"])
    s = paper.synth
    assert (s.retime_detail_frames, s.blend_detail_frames, s.retime_min_speed, s.loop_penalty,
            s.transition_penalty) == (0, 0, 0.0, 0.0, 0.0)
    assert quality.synth.retime_detail_frames == 3 and quality.synth.blend_detail_frames == 3
    assert (quality.synth.retime_min_speed, quality.synth.loop_penalty, quality.synth.transition_penalty) == (0, 0, 0)


def two_clause_graph(frames=70):
    """Clip c0 has two PCs, [10, 20) and [30, 40) (peaks at 15 and 35: a recorded pause of 10 frames);
    clips c1 and c2 one PC [10, 20) each. Idle frames jump to any clip's frames 0, 3 and 6 (synthetic,
    cost 1), so a path can reach a clause at almost any output frame, at the price of a transition."""
    own, clip, frame, st, en, pk = [], [], [], [], [], []
    n_clips = 3
    for c in range(n_clips):
        lab = np.zeros(frames, np.int8)
        s_, e_, p_ = (np.full(frames, -1) for _ in range(3))
        for a in ((10, 30) if c == 0 else (10,)):
            lab[a:a + 10] = PC
            s_[a:a + 10], e_[a:a + 10], p_[a:a + 10] = a, a + 10, a + 5
        own.append(lab); clip.append(np.full(frames, c)); frame.append(np.arange(frames))
        st.append(s_); en.append(e_); pk.append(p_)
    return _labelled_graph(own, clip, frame, st, en, pk, frames, lambda c, f: own[c][f] == 0 or f == frames - 1)


def test_start_slack_lets_one_recorded_run_cover_two_clauses_with_another_pause():
    """The input's two clauses are 14 frames apart, the recording's 10. With the start tolerance (1
    frame) the second clause must be entered by a synthetic transition; with search.start_slack_factor
    0.5 (slack floor(0.5 * 14) = 7 frames) one run of c0 plays both, with no transition, the warp moves
    the second clause onto the input's times and the independent checker confirms every constraint
    through it (and refuses the same path without the warp). The beam kernel and its NumPy reference
    take the same path under the slack rule."""
    from convsynth_jax.search.retime import retime_knots

    g, audio = two_clause_graph()
    own = pd.DataFrame([("PC", 1.0, 1.5, 2.0), ("PC", 3.4, 3.9, 4.4)], columns=["kind", "start", "peak", "end"])
    T = 60
    base = SearchParams(tolerance=0.1, beam_size=64, max_degree=32, retime_factor=0.3, temperature=0.05)
    runs = {}
    for f in (0.0, 0.5):
        cfg = dataclasses.replace(base, start_slack_factor=f)
        cons = build_constraints(own, None, T, FPS, cfg)
        res = beam_search(g, cons, cfg, seed=0)
        assert res.success
        warp = retime_knots(g, cons, res.path, cfg.retime_factor)
        clips = np.array([g.clip_names[g.clip[s]] for s in res.path])
        chk = check_path(clips, g.frame[res.path], audio, own, None, FPS, 0.1, warp=warp)
        assert chk["met"] == chk["total"], chk
        runs[f] = (res, clips, warp)
    assert runs[0.0][0].num_synthetic_transitions >= 1
    res, clips, warp = runs[0.5]
    assert res.num_synthetic_transitions == 0 and (clips == "c0").all()
    raw = check_path(clips, g.frame[res.path], audio, own, None, FPS, 0.1)
    assert raw["met"] < raw["total"]
    # the second clause's start: the recording's frame 30 shows at the input's 34
    out_k, path_k = warp
    assert abs(np.interp(34, out_k, path_k) - (30 - g.frame[res.path[0]])) < 1e-9
    cfg = dataclasses.replace(base, start_slack_factor=0.5, retry_temperatures=[], retry_beam_size=0, lookahead=False)
    cons = build_constraints(own, None, T, FPS, cfg)
    ref = reference_beam_search(g, cons, cfg, seed=1, temperature=cfg.temperature)
    got = beam_search(g, cons, cfg, seed=1)
    assert ref.success and got.success
    np.testing.assert_array_equal(got.path, ref.path)


def test_start_slack_needs_retiming_and_a_factor_below_one():
    from convsynth_jax.errors import ConfigError

    own = pd.DataFrame([("PC", 1.0, 1.5, 2.0)], columns=["kind", "start", "peak", "end"])
    with pytest.raises(ConfigError, match="start_slack_factor > 0 needs search.retime_factor"):
        build_constraints(own, None, 40, FPS, SearchParams(start_slack_factor=0.5))
    with pytest.raises(ConfigError, match="start_slack_factor must lie in"):
        build_constraints(own, None, 40, FPS, SearchParams(retime_factor=0.2, start_slack_factor=1.0))
    # the slack is floor(factor * gap) and widens the entry window and the free range, not the idle naming
    c0 = build_constraints(own, None, 40, FPS, SearchParams(retime_factor=0.2))
    c5 = build_constraints(own, None, 40, FPS, SearchParams(retime_factor=0.2, start_slack_factor=0.5))
    assert (c0.paper.own_kind >= 0).sum() == 3 and (c5.paper.own_kind >= 0).sum() == 3 + 2 * 5
    assert (c5.paper.own_start_tol[c5.paper.own_kind >= 0] == 1 + 5).all()
    assert (c5.own_req[4:9] == -1).all() and c0.own_req[4] == 0
    assert [s for s in c5.segments if s["kind"] == "idle"] == [s for s in c0.segments if s["kind"] == "idle"]


def test_checker_reads_a_stretched_pause_as_idle_up_to_the_warped_start():
    """A path plays two listener responses of one recording 2 frames apart ([10, 20) and [22, 32)); the
    warp puts the second at the input's [30, 40), stretching the 2-frame pause over 10 output frames.
    Each output frame shows the label of the path frame its path time lies in, so the pause reads idle
    up to frame 30, where the warp places the response. (Read at the nearest path frame, output frames
    28 and 29 showed the response's first frame: an idle run the checker failed although the response
    is placed exactly.)"""
    from convsynth_jax.annotate.types import LR

    n = 60
    lab = np.zeros(n, np.int8)
    st, en = np.full(n, -1, np.int32), np.full(n, -1, np.int32)
    for a in (10, 22):
        lab[a:a + 10] = LR
        st[a:a + 10], en[a:a + 10] = a, a + 10
    audio = {"c0": (FrameAudio(lab, st, en, np.full(n, -1, np.int32)),
                    FrameAudio(np.zeros(n, np.int8), *(np.full(n, -1, np.int32),) * 3))}
    own = pd.DataFrame([("LR", 1.0, np.nan, 2.0), ("LR", 3.0, np.nan, 4.0)], columns=["kind", "start", "peak", "end"])
    T = 50
    warp = (np.array([0.0, 10, 20, 30, 40, 49]), np.array([0.0, 10, 20, 22, 32, 49]))
    chk = check_path(["c0"] * T, np.arange(T), audio, own, None, FPS, 0.1, warp=warp)
    assert chk["met"] == chk["total"], [d for d in chk["details"] if not d["met"]]
    # a control where it must fail: the second response warped to start 2 frames late leaves it unmatched
    late = (np.array([0.0, 10, 20, 32, 42, 49]), np.array([0.0, 10, 20, 22, 32, 49]))
    bad = check_path(["c0"] * T, np.arange(T), audio, own, None, FPS, 0.1, warp=late)
    unmet = {(d["kind"], d["start"]) for d in bad["details"] if not d["met"]}
    assert ("LR", 30) in unmet and ("LR", 10) not in unmet
