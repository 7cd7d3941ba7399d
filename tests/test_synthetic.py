import filecmp
import json

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from convsynth_jax.data import ensure_synthetic_corpus, make_synthetic_corpus, resolve_config
from convsynth_jax.errors import ConfigError
from convsynth_jax.io import load_bvh, load_corpus
from tolerances import F0_RELATIVE

SMALL = {"num_sessions": 2, "session_seconds": 20.0}
MOTION_ONLY = {"num_sessions": 8, "session_seconds": 120.0, "write_audio": False}


@pytest.fixture(scope="module")
def motion_corpus(tmp_path_factory):
    """A moderately sized corpus without audio (a few seconds to write): rates and kinematics."""
    return make_synthetic_corpus(tmp_path_factory.mktemp("synth") / "c", MOTION_ONLY)


def test_same_seed_same_bytes_other_seed_differs(tmp_path):
    a = make_synthetic_corpus(tmp_path / "a", SMALL)
    b = make_synthetic_corpus(tmp_path / "b", SMALL)
    c = make_synthetic_corpus(tmp_path / "c", {**SMALL, "seed": 1})
    names = sorted(p.name for p in a.iterdir())
    assert names == sorted(p.name for p in b.iterdir()) and len(names) == 2 * 6 + 2
    match, mismatch, errors = filecmp.cmpfiles(a, b, names, shallow=False)
    assert mismatch == [] and errors == []
    assert not filecmp.cmp(a / "session01_main-agent.bvh", c / "session01_main-agent.bvh", shallow=False)


def test_written_corpus_loads(tmp_path):
    root = make_synthetic_corpus(tmp_path / "c", SMALL)
    corpus = load_corpus(root)
    assert corpus.characters == ["female", "male"]
    m = corpus.sessions[0].participants[0].load_motion()
    assert 25 <= m.skeleton.num_joints <= 35 and m.fps == 30
    assert abs(m.root_positions[:, 1].mean() - 48) < 3  # the root stays near the chair
    ev = pd.read_csv(root / "events.csv")
    assert set(ev["kind"]) <= {"PC", "LR", "HP", "LH", "RH", "Nod"}
    assert {"session", "participant", "kind", "start", "peak", "end"} <= set(ev.columns)


def test_invalid_probabilities_rejected():
    with pytest.raises(ConfigError):
        resolve_config({"characters": {"main-agent": {"p_pc_either": 0.3}}})


def test_planted_rates_match_configuration(motion_corpus):
    """On a corpus without audio (fast), planted gesture/nod rates agree with the configured
    probabilities: a two-sided binomial test must not reject at the 0.1% level."""
    ev = pd.read_csv(motion_corpus / "events.csv")
    cfg = resolve_config({})
    for role, ch in cfg["characters"].items():
        own = ev[ev["participant"] == role]
        src = own[own["kind"].isin(["LH", "RH", "Nod"])]
        n_pc = int((own["kind"] == "PC").sum())
        for kind, p in (("LH", ch["p_pc_lh"]), ("RH", ch["p_pc_rh"])):
            k = int(((src["kind"] == kind) & (src["source"] == "PC")).sum())
            assert stats.binomtest(k, n_pc, p).pvalue > 1e-3, (role, kind, k, n_pc, p)
        pc_gest = src[src["source"] == "PC"]
        either = pc_gest.groupby(["session", "cause_start"]).ngroups  # clauses with at least one gesture
        assert stats.binomtest(either, n_pc, ch["p_pc_either"]).pvalue > 1e-3
        n_lr = int((own["kind"] == "LR").sum())
        k = int(((src["kind"] == "Nod") & (src["source"] == "LR")).sum())
        assert stats.binomtest(k, n_lr, ch["p_lr_nod"]).pvalue > 1e-3
        partner = ev[(ev["participant"] != role) & (ev["kind"] == "HP")]
        k = int(((src["kind"] == "Nod") & (src["source"] == "HP")).sum())
        assert stats.binomtest(k, len(partner), ch["p_ph_nod"]).pvalue > 1e-3


def test_praat_recovers_planted_f0_and_words_are_voiced():
    import parselmouth

    from convsynth_jax.data.synthetic import _conversation, _render_voice

    cfg = resolve_config({})
    rng = np.random.default_rng(5)
    segs = _conversation(rng, cfg, 20.0, 1.0)
    for role, f0b in (("main-agent", 210.0), ("interloctr", 118.0)):
        own = [s for s in segs if s.role == role]
        sig, f0 = _render_voice(own, f0b, 20.0, 16000, rng, cfg["accent_rise"])
        pitch = parselmouth.Sound(sig, 16000).to_pitch(time_step=0.01, pitch_floor=75, pitch_ceiling=500)
        t, f = pitch.xs(), pitch.selected_array["frequency"]
        planted = f0[np.clip((t * 16000).astype(int), 0, len(f0) - 1)]
        both = (f > 0) & (planted > 0)
        assert both.sum() > 100
        rel = np.abs(f[both] - planted[both]) / planted[both]
        assert np.mean(rel < F0_RELATIVE) > 0.98
        # transcript words lie where the signal is voiced
        words = [w for s in own for w in s.words]
        mids = np.array([(w[0] + w[1]) / 2 for w in words])
        idx = np.clip(np.searchsorted(t, mids), 0, len(t) - 1)
        assert np.mean(f[idx] > 0) > 0.9


def _union_length(intervals, lo, hi):
    """Length of the union of ``intervals`` clipped to [lo, hi], on a 1 ms grid (independent of the
    generator's interval code)."""
    grid = np.zeros(int(round((hi - lo) * 1000)), bool)
    for a, b in intervals:
        i, j = int(np.clip(round((a - lo) * 1000), 0, grid.size)), int(np.clip(round((b - lo) * 1000), 0, grid.size))
        grid[i:j] = True
    return grid.sum() / 1000.0


def test_spontaneous_movements_away_from_windows_at_configured_rate(motion_corpus):
    """Spontaneous gestures and nods lie outside the participant's own candidate windows (twice the
    segment length around it) and its partner's hesitation windows, keep 0.3 s from its other
    events, and their number matches rate x available time (Poisson test)."""
    ev = pd.read_csv(motion_corpus / "events.csv")
    meta = json.loads((motion_corpus / "corpus.json").read_text())
    cfg = resolve_config({})
    total_free, total_n = 0.0, 0
    for sess in meta["sessions"]:
        for role in ("main-agent", "interloctr"):
            e = ev[ev.session == sess["name"]]
            audio = e[e.kind.isin(["PC", "LR", "HP"]) & ((e.participant == role) | (e.kind == "HP"))]
            win = [(r.start - (r.end - r.start) / 2, r.end + (r.end - r.start) / 2) for r in audio.itertuples()]
            motion = e[(e.participant == role) & e.kind.isin(["LH", "RH", "Nod"])]
            sp, caused = motion[motion.source == "spontaneous"], motion[motion.source != "spontaneous"]
            for r in sp.itertuples():
                assert all(r.end <= a or r.start >= b for a, b in win), (sess["name"], role, r)
                assert all(r.end + 0.3 <= c.start or r.start >= c.end + 0.3 for c in caused.itertuples())
            busy = win + [(c.start - 0.4, c.end + 0.4) for c in caused.itertuples()]
            dur = sess["duration"]
            free = (dur - 2.5) - _union_length(busy, 1.0, dur - 1.5)
            assert abs(free - sess["spontaneous_free_seconds"][role]) < 0.05
            total_free += free
            total_n += len(sp)
    expected = cfg["spontaneous_per_minute"] * total_free / 60.0
    assert total_n > 0
    assert stats.poisson.cdf(total_n, expected) > 5e-4 and stats.poisson.sf(total_n - 1, expected) > 5e-4


def test_same_channel_events_keep_idle_between(motion_corpus):
    """Consecutive events of the same hand (or of the head) leave at least min_event_gap of idle, so a
    threshold segmenter can find both edges."""
    ev = pd.read_csv(motion_corpus / "events.csv")
    gap = resolve_config({})["min_event_gap"]
    for (_, _, kind), g in ev[ev.kind.isin(["LH", "RH", "Nod"])].groupby(["session", "participant", "kind"]):
        g = g.sort_values("start")
        assert (g.start.values[1:] - g.end.values[:-1] >= gap - 1e-3).all(), kind
        assert ((g.start < g.peak) & (g.peak < g.end)).all()


def test_gestures_and_nods_move_clearly_above_idle(motion_corpus):
    """Planted gestures: hand speed relative to the shoulder peaks well above idle; nods: the forehead
    (the head's End Site) moves a few centimetres vertically."""
    from scipy.spatial.transform import Rotation

    from convsynth_jax.kinematics import global_transforms

    ev = pd.read_csv(motion_corpus / "events.csv")
    for role in ("main-agent", "interloctr"):
        m = load_bvh(motion_corpus / f"session01_{role}.bvh")
        pos, rot = (np.asarray(x, np.float64) for x in global_transforms(m))
        t = np.arange(len(pos)) / m.fps
        e = ev[(ev.session == "session01") & (ev.participant == role)]
        busy = np.zeros(len(t), bool)
        for r in e[e.kind.isin(["LH", "RH", "Nod"])].itertuples():
            busy |= (t >= r.start - 0.2) & (t <= r.end + 0.2)
        names = list(m.skeleton.names)
        for side, kind in (("Left", "LH"), ("Right", "RH")):
            rel = pos[:, names.index(f"{side}Hand")] - pos[:, names.index(f"{side}Shoulder")]
            speed = np.linalg.norm(np.gradient(rel, axis=0), axis=1) * m.fps
            idle = np.percentile(speed[~busy], 95)
            assert 0.2 < idle < 15.0  # never perfectly still, but calm (cm/s)
            for r in e[e.kind == kind].itertuples():
                inside = (t >= r.start) & (t <= r.end)
                assert speed[inside].max() > 5 * idle, (role, kind, r.start)
        head = names.index("Head")
        tip = pos[:, head] + Rotation.from_quat(rot[:, head][:, [1, 2, 3, 0]]).apply(dict(m.skeleton.end_sites)[head])
        for r in e[e.kind == "Nod"].itertuples():
            inside = (t >= r.start) & (t <= r.end)
            assert 1.0 < np.ptp(tip[inside, 1]) < 8.0, (role, r.start)


def test_praat_finds_the_planted_accent_peaks():
    """The clause's F0 maximum measured by Praat lies at the planted peak (the stressed word)."""
    import parselmouth

    from convsynth_jax.data.synthetic import _conversation, _render_voice

    cfg = resolve_config({})
    rng = np.random.default_rng(7)
    segs = _conversation(rng, cfg, 30.0, 1.0)
    own = [s for s in segs if s.role == "main-agent"]
    sig, _ = _render_voice(own, 210.0, 30.0, 16000, rng, cfg["accent_rise"])
    pitch = parselmouth.Sound(sig, 16000).to_pitch(time_step=0.01, pitch_floor=75, pitch_ceiling=500)
    t, f = pitch.xs(), pitch.selected_array["frequency"]
    pcs = [s for s in own if s.kind == "PC"]
    assert len(pcs) >= 3
    for s in pcs:
        inside = (t >= s.start) & (t <= s.end) & (f > 0)
        assert abs(t[inside][np.argmax(f[inside])] - s.peak) < 0.05


def test_ensure_reuses_or_regenerates(tmp_path):
    corpus_cfg = {"name": "syn", "root": None, "generator": {**SMALL, "num_sessions": 1, "write_audio": False}}
    root = ensure_synthetic_corpus(corpus_cfg, tmp_path)
    assert root == tmp_path / "syn" and (root / "corpus.json").is_file()
    stamp = (root / "corpus.json").stat().st_mtime_ns
    assert ensure_synthetic_corpus(corpus_cfg, tmp_path) == root
    assert (root / "corpus.json").stat().st_mtime_ns == stamp  # reused, not rewritten
    other = {**corpus_cfg, "generator": {**corpus_cfg["generator"], "seed": 4}}
    ensure_synthetic_corpus(other, tmp_path)
    meta = json.loads((root / "corpus.json").read_text())
    assert meta["seed"] == 4 and meta["characters"] == {"main-agent": "female", "interloctr": "male"}
    assert not list(tmp_path.glob(".syn.*"))  # no temporary folder left behind
