import numpy as np
import pandas as pd
import pytest

from convsynth_jax.annotate.audio import add_peaks, annotate_audio, load_word_corpus, segment_words
from convsynth_jax.annotate.motion import Window, candidate_windows, detect_in_window, idle_threshold
from convsynth_jax.annotate.types import FrameAudio
from convsynth_jax.errors import LabelError


def words(rows):
    return pd.DataFrame(rows, columns=["start", "end", "word"])


def test_segment_words_groups_clauses_and_labels_tokens():
    w = words([(0.0, 0.2, "so"), (0.25, 0.5, "we"), (0.55, 0.9, "went"),   # clause 1
               (1.5, 1.8, "home"),                                        # gap 0.6 > 0.3: clause 2
               (1.85, 2.1, "uh"),                                         # HP splits
               (2.15, 2.4, "and"), (2.45, 2.6, "you"), (2.6, 2.8, "know"),  # "you know" is HP
               (3.0, 3.3, "I"), (3.3, 3.5, "see")])                        # "I see" is LR
    seg = segment_words(w, load_word_corpus(), max_gap=0.3)
    assert seg["kind"].tolist() == ["PC", "PC", "HP", "PC", "HP", "LR"]
    assert seg["text"].tolist() == ["so we went", "home", "uh", "and", "you know", "I see"]
    assert seg.loc[0, "end"] == 0.9


def test_ibm_hesitation_token_is_hp():
    seg = segment_words(words([(0, 0.3, "so"), (0.35, 0.8, "%HESITATION"), (0.9, 1.0, "ok")]), load_word_corpus())
    assert seg["kind"].tolist() == ["PC", "HP", "LR"]


def test_peak_is_f0_maximum_inside_segment():
    seg = pd.DataFrame({"kind": ["PC", "PC"], "start": [0.0, 1.0], "end": [0.5, 1.5], "text": ["a", "b"]})
    t = np.arange(0, 2, 0.01)
    f0 = 100 + 50 * np.exp(-((t - 0.3) / 0.05) ** 2)
    f0[(t > 0.95) & (t < 1.6)] = np.nan  # second segment unvoiced
    out = add_peaks(seg, t, f0)
    assert out.loc[0, "peak"] == pytest.approx(0.3, abs=0.011)
    assert out.loc[1, "peak"] == pytest.approx(1.25)  # midpoint when unvoiced


def test_eq1_eq2_thresholds_by_hand():
    v = np.array([2.0, 4.0, 12.0, 22.0, 2.0])
    assert idle_threshold(v, 0.1) == pytest.approx(2.0 + 0.1 * 20.0)
    # movement window: theta_W over frames 1..3 = 4 + 0.1 * 18 = 5.8 -> frames 2, 3 above
    assert detect_in_window(v, Window(1, 4), theta_s=5.0) == (2, 3, 4)
    assert detect_in_window(v, Window(0, 2), theta_s=5.0) is None  # never above the clip threshold


def test_figure3_windows_expand_and_trim():
    seg = pd.DataFrame({"start": [1.0, 2.2, 5.0], "end": [2.0, 3.0, 5.5]})
    w = candidate_windows(seg, num_frames=300, fps=10)
    # 1: [0.5, 2.5] trimmed at the next segment's start 2.2 -> frames [5, 22)
    assert w[0] == Window(5, 22)
    # 2: [1.8, 3.4] trimmed at the previous end 2.0 -> [20, 34)
    assert w[1] == Window(20, 34)
    # 3: [4.75, 5.75] no neighbour in reach
    assert w[2] == Window(47, 58)


def test_frame_audio_from_segments_and_unknown_label():
    seg = pd.DataFrame({"kind": ["PC", "LR"], "start": [0.1, 0.5], "end": [0.3, 0.6], "peak": [0.2, np.nan]})
    fa = FrameAudio.from_segments(seg, 10, 10.0)
    assert fa.label.tolist() == [0, 1, 1, 0, 0, 2, 0, 0, 0, 0]
    assert fa.seg_start[2] == 1 and fa.seg_end[2] == 3 and fa.seg_peak[2] == 2 and fa.seg_peak[5] == -1
    with pytest.raises(LabelError):
        FrameAudio.from_segments(pd.DataFrame({"kind": ["XX"], "start": [0.0], "end": [0.1]}), 5, 10.0)


def _match(planted, detected, kind):
    p = planted[planted["kind"] == kind]
    d = detected[detected["kind"] == kind]
    hit_p = sum(((d["start"] < r.end) & (d["end"] > r.start)).any() for r in p.itertuples())
    hit_d = sum(((p["start"] < r.end) & (p["end"] > r.start)).any() for r in d.itertuples())
    return hit_p, len(p), hit_d, len(d)


@pytest.fixture(scope="module")
def tiny_annotations(tiny_corpus_dir):
    from convsynth_jax.annotate.pipeline import annotate_corpus
    from convsynth_jax.config import compose
    from convsynth_jax.io import load_corpus

    return annotate_corpus(load_corpus(tiny_corpus_dir), compose(["corpus=synthetic_tiny"]), progress=False)


def test_audio_segments_match_planted(tiny_corpus_dir, tiny_annotations):
    ev = pd.read_csv(tiny_corpus_dir / "events.csv")
    for s, parts in tiny_annotations.items():
        for role, a in parts.items():
            pl = ev[(ev.session == s) & (ev.participant == role) & ev.kind.isin(["PC", "LR", "HP"])].reset_index()
            assert a.segments["kind"].tolist() == pl["kind"].tolist()
            np.testing.assert_allclose(a.segments["start"], pl["start"], atol=0.01)
            assert np.abs(a.segments["peak"] - pl["peak"]).max() < 0.05  # Praat finds the planted accent


def test_detected_motion_events_match_planted(tiny_corpus_dir, tiny_annotations):
    """Precision and recall of window-based detection against planted events caused by audio
    (spontaneous movements lie outside every candidate window by construction)."""
    ev = pd.read_csv(tiny_corpus_dir / "events.csv")
    tot = np.zeros(4)
    for s, parts in tiny_annotations.items():
        for role, a in parts.items():
            pl = ev[(ev.session == s) & (ev.participant == role) & ev.kind.isin(["LH", "RH", "Nod"])
                    & (ev.source != "spontaneous")]
            for k in ("LH", "RH", "Nod"):
                tot += _match(pl, a.events, k)
    recall, precision = tot[0] / tot[1], tot[2] / tot[3]
    assert recall >= 0.9 and precision >= 0.9, (recall, precision)


def test_cooccurrence_rates_significant_and_negative_control(tiny_annotations):
    from convsynth_jax.annotate.pipeline import ParticipantAnnotation
    from convsynth_jax.stats.cooccurrence import cooccurrence_table

    parts = [a for s in tiny_annotations.values() for a in s.values()]
    t = cooccurrence_table(parts)
    pc = t[t["hypothesis"].str.startswith("PC")]
    assert (pc["p_chi2"] < 1e-3).all() and (pc["p_permutation"] < 1e-3).all()
    assert (pc["rate"] > pc["chance_rate"] + 0.3).all()
    # negative control: audio of each session paired with the motion of another session
    names = list(tiny_annotations)
    swapped = []
    for i, s in enumerate(names):
        other = tiny_annotations[names[(i + 1) % len(names)]]
        for role, a in tiny_annotations[s].items():
            swapped.append(ParticipantAnnotation(s, role, a.character, other[role].motion, a.segments,
                                                 a.partner_segments, a.events, a.own, a.partner))
    ctrl = cooccurrence_table(swapped)
    ctrl_pc = ctrl[ctrl["hypothesis"].str.startswith("PC")]
    # no co-occurrence ABOVE chance (the one-sided permutation test; the two-sided chi-square may flag
    # the opposite direction, since random windows then fall where the other session's speaker moved)
    assert (ctrl_pc["p_permutation"] > 0.01).all(), ctrl_pc[["character", "hypothesis", "rate", "chance_rate", "p_permutation"]]
    assert not ((ctrl_pc["rate"] > ctrl_pc["chance_rate"]) & (ctrl_pc["p_chi2"] < 0.01)).any()


def test_real_speech_segmentation(speech_dir):
    from convsynth_jax.io import load_audio, load_transcript

    for name in ("acoustic_corpus", "cold_corpus"):
        w = load_transcript(speech_dir / f"{name}.TextGrid")
        seg = annotate_audio(w, load_audio(speech_dir / f"{name}.wav"), {})
        fillers = w[w["word"].isin(["uh", "um", "yknow"])]
        hp = seg[seg["kind"] == "HP"]
        assert len(hp) == len(fillers) > 0
        assert ((seg["peak"] >= seg["start"]) & (seg["peak"] <= seg["end"])).all()
        voiced = seg["f0_peak"].dropna()
        assert len(voiced) >= 0.7 * len(seg) and voiced.between(60, 450).all()
