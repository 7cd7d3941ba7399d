import filecmp

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from convsynth_jax.data import make_synthetic_corpus, resolve_config
from convsynth_jax.errors import ConfigError
from convsynth_jax.io import load_bvh, load_corpus
from tolerances import F0_RELATIVE

SMALL = {"num_sessions": 2, "session_seconds": 20.0}


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


def test_planted_rates_match_configuration(tmp_path):
    """On a corpus without audio (fast), planted gesture/nod rates agree with the configured
    probabilities: a two-sided binomial test must not reject at the 0.1% level."""
    root = make_synthetic_corpus(tmp_path / "c", {"num_sessions": 8, "session_seconds": 120.0, "write_audio": False})
    ev = pd.read_csv(root / "events.csv")
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
