"""Scores of the annotation pipeline against a planted ground truth (the synthetic corpus's
``events.csv``): detected motion events and audio segments against the planted ones.

* :func:`overlap_counts`: a planted segment is found when a detected one overlaps it, a detected one
  is right when it overlaps a planted one (recall = found / planted, precision = right / detected).
* :func:`near`: for each time, whether another list holds one within a tolerance (clause boundaries).
* :func:`detection_scores`: motion events (LH, RH, Nod) per recording; recall over the movements the
  generator caused by audio, precision over every planted movement (spontaneous ones included).
* :func:`audio_scores`: clause boundaries (every start and end, matched within ``tolerance`` s),
  words per clause detected and planted, LR and HP by overlap.
* :func:`planted_rate`, :func:`negative_control`, :func:`hand_decomposition`: Table 1's rates against
  what the generator planted, controls that must not beat chance, and why the hand rates differ.
* :func:`fluent_clause_scores`, :func:`real_speech_scores`: clause segmentation on fluent synthetic
  speech and on real recordings.

``experiments/analysis/eval_annotation.py`` runs them on the default corpus with controls.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pandas as pd

from ..annotate.kinds import hypotheses

CLAUSE_TOLERANCE_S = 0.15    # a planted clause boundary is matched by a detected one within this
# the hypothesis table (audio kind, motion kinds, channel), the registry's
_SPEC = {h.name: (h.label, list(h.motions), h.channel) for h in hypotheses()}


def overlap_counts(planted: pd.DataFrame, detected: pd.DataFrame) -> tuple[int, int, int, int]:
    """(planted found, planted, detected right, detected) of two segment tables (start, end; s)."""
    hp = sum(bool(((detected["start"] < r.end) & (detected["end"] > r.start)).any()) for r in planted.itertuples())
    hd = sum(bool(((planted["start"] < r.end) & (planted["end"] > r.start)).any()) for r in detected.itertuples())
    return int(hp), len(planted), int(hd), len(detected)


def near(a, b, tolerance: float) -> np.ndarray:
    """(len(a),) bool: for each value of ``a``, is there a value of ``b`` within ``tolerance``."""
    a, b = np.asarray(a, float), np.sort(np.asarray(b, float))
    if not b.size:
        return np.zeros(a.size, bool)
    i = np.clip(np.searchsorted(b, a), 1, b.size) - 1
    j = np.clip(i + 1, 0, b.size - 1)
    return np.minimum(np.abs(a - b[i]), np.abs(a - b[j])) <= tolerance


def words_stats(n_words) -> dict:
    """Summary of words per clause: count, mean, sd, median, max, clauses over 15 words, histogram."""
    n = np.asarray(n_words, int)
    if not n.size:
        return {"clauses": 0}
    return {"clauses": int(n.size), "mean": float(n.mean()), "sd": float(n.std()), "median": float(np.median(n)),
            "max": int(n.max()), "over_15": int((n > 15).sum()),
            "histogram": {int(k): int(v) for k, v in zip(*np.unique(n, return_counts=True))}}


def detection_scores(ann: dict, events: pd.DataFrame, kinds=("LH", "RH", "Nod")) -> dict:
    """Motion-event detection against the planted events. ann: session -> role -> annotation with
    ``events`` (kind, start, end); events: the planted table (session, participant, kind, start,
    end, source; source "spontaneous" for movements no audio caused)."""
    per_kind = {}
    for s, parts in ann.items():
        for role, a in parts.items():
            pl = events[(events.session == s) & (events.participant == role)]
            caused = pl[pl.source != "spontaneous"]
            for k in kinds:
                d = a.events[a.events.kind == k].drop_duplicates(["start", "end"])
                hp, n_p, _, _ = overlap_counts(caused[caused.kind == k], d)
                _, _, hd, n_d = overlap_counts(pl[pl.kind == k], d)
                per_kind[k] = per_kind.get(k, np.zeros(4)) + (hp, n_p, hd, n_d)
    tot = sum(per_kind.values())
    return {"recall": tot[0] / max(tot[1], 1), "precision": tot[2] / max(tot[3], 1), "planted_caused": int(tot[1]),
            "detected": int(tot[3]),
            "per_kind": {k: {"recall": v[0] / max(v[1], 1), "precision": v[2] / max(v[3], 1)} for k, v in per_kind.items()}}


def audio_scores(ann: dict, events: pd.DataFrame, tolerance: float = CLAUSE_TOLERANCE_S) -> dict:
    """Clause boundary precision/recall (start and end of every clause, matched within ``tolerance``),
    words per clause detected vs planted, LR/HP overlap precision/recall. ann: session -> role ->
    annotation with ``segments`` (kind, start, end, text); events: the planted PC/LR/HP rows."""
    hits = {k: np.zeros(4) for k in ("PC", "LR", "HP")}
    det_words, pl_words = [], []
    for s, parts in ann.items():
        for role, a in parts.items():
            pl = events[(events.session == s) & (events.participant == role)]
            seg = a.segments
            p_pc, d_pc = pl[pl.kind == "PC"], seg[seg.kind == "PC"]
            pb = np.concatenate([p_pc.start, p_pc.end])
            db = np.concatenate([d_pc.start, d_pc.end])
            hits["PC"] += (near(pb, db, tolerance).sum(), pb.size, near(db, pb, tolerance).sum(), db.size)
            det_words += d_pc.text.str.split().str.len().tolist()
            pl_words += p_pc.text.str.split().str.len().tolist()
            for k in ("LR", "HP"):
                hits[k] += overlap_counts(pl[pl.kind == k], seg[seg.kind == k])
    out = {k: {"recall": v[0] / max(v[1], 1), "precision": v[2] / max(v[3], 1), "planted": int(v[1]),
               "detected": int(v[3])} for k, v in hits.items()}
    out["PC"]["tolerance_s"] = tolerance
    out["words_per_clause"] = {"detected": words_stats(det_words), "planted": words_stats(pl_words)}
    return out


def planted_rate(events: pd.DataFrame, role: str, hypothesis: str) -> float:
    """The generator's realised rate of ``hypothesis`` for the character ``role``: audio segments of the
    hypothesis's kind (own or the partner's, by its channel) after which the generator planted one of its
    motion kinds, over all such audio segments (``events``: the corpus's events.csv)."""
    ev = events
    akind, kinds, whose = _SPEC[hypothesis]
    who = (ev.participant == role) if whose == "own" else (ev.participant != role)
    audio = ev[(ev.kind == akind) & who]
    caused = ev[(ev.participant == role) & (ev.source == akind) & ev.kind.isin(kinds)]
    return caused.groupby(["session", "cause_start"]).ngroups / max(1, len(audio))


def negative_control(ann: dict, how: str) -> list:
    """Every participant's annotation with motion that does not belong to its audio: ``how="swap"``, the
    same role's motion of the next session (cut to this one's length); ``"shift"``, its own motion rolled
    circularly by a third of the clip. Co-occurrence over these must not beat chance."""
    if how not in ("swap", "shift"):
        raise ValueError(f"negative control {how!r}: expected 'swap' or 'shift'")
    names = list(ann)
    out = []
    for i, s in enumerate(names):
        for role, a in ann[s].items():
            if how == "swap":
                m = ann[names[(i + 1) % len(names)]][role].motion
                m = m.slice(0, min(m.num_frames, a.motion.num_frames))
            else:
                k = a.motion.num_frames // 3
                m = dataclasses.replace(a.motion, rotations=np.roll(a.motion.rotations, k, 0),
                                        translations=np.roll(a.motion.translations, k, 0))
            out.append(dataclasses.replace(a, motion=m))
    return out


def hand_decomposition(ann: dict, events: pd.DataFrame, glitches: pd.DataFrame, params) -> dict:
    """Hand co-occurrence decomposed, {(character role, hypothesis): counts}: per character and hand over
    the planted clauses (``events``), the pipeline's detector and counter (``hypothesis_matches`` on the
    recording's speeds and Eq. 1 thresholds) against the planted truth: caused and detected, caused and
    missed, not caused but detected (split by what the detected movement overlaps: a gesture planted for
    another clause, a spontaneous one, a glitch of that arm in ``glitches``, nothing planted), and how the
    generator's interval emulation ``window_matches`` counts the same clauses. ``params``: AnnotateParams."""
    from ..annotate.motion import joint_speeds, recording_thresholds, segment_windows
    from ..data.synthetic import window_matches
    from ..stats.cooccurrence import hypothesis_matches

    ap, ev = params, events
    out = {}
    for s, parts in ann.items():
        for role, a in parts.items():
            sp = joint_speeds(a.motion, ap)
            thr = recording_thresholds(sp, ap.alpha_s)
            fps = a.motion.fps
            e = ev[ev.session == s]
            chans = {r: e[(e.participant == r) & e.kind.isin(["PC", "LR", "HP"])].sort_values("start")
                     for r in e.participant.unique()}
            own = chans[role]
            partner = next((c for r, c in chans.items() if r != role), own.iloc[:0])
            pcs = own[own.kind == "PC"]
            for h, side in (("PC-LH", "Left"), ("PC-RH", "Right")):
                k = _SPEC[h][1][0]
                mv = e[(e.participant == role) & (e.kind == k)]
                det, wins = hypothesis_matches(sp, own, partner, fps, h, thresholds=thr, alpha_w=ap.alpha_w,
                                               extend_trim=ap.extend_trim)
                found = segment_windows(sp[k], wins, float(thr[k]), ap.alpha_w, extend_trim=ap.extend_trim)
                emu = window_matches(pcs[["start", "end"]].values, own[["start", "end"]].values,
                                     mv[["start", "end"]].values)
                caused = np.array([((mv.source == "PC") & (np.abs(mv.cause_start - r.start) < 1e-3)).any()
                                   for r in pcs.itertuples()])
                c = out.setdefault((role, h), {x: 0 for x in (
                    "clauses", "caused", "detected", "window_matches", "caused_detected", "caused_missed",
                    "not_caused_detected_other_clause_gesture", "not_caused_detected_spontaneous",
                    "not_caused_detected_glitch", "not_caused_detected_nothing_planted",
                    "caused_detected_window_matches_misses")})
                c["clauses"] += len(pcs)
                c["caused"] += int(caused.sum())
                c["detected"] += int(det.sum())
                c["window_matches"] += int(emu.sum())
                c["caused_detected"] += int((caused & det).sum())
                c["caused_missed"] += int((caused & ~det).sum())
                c["caused_detected_window_matches_misses"] += int((caused & det & ~emu).sum())
                g = glitches[(glitches.session == s) & (glitches.participant == role)
                             & glitches.joint.str.startswith(side)]
                for i in np.flatnonzero(~caused & det):
                    f0, f1 = found[i][0], found[i][2]
                    ov = mv[(mv.start < f1 / fps) & (mv.end > f0 / fps)]
                    if (ov.source == "PC").any():
                        c["not_caused_detected_other_clause_gesture"] += 1
                    elif len(ov):
                        c["not_caused_detected_spontaneous"] += 1
                    elif ((g.start_frame < f1) & (g.end_frame > f0)).any():
                        c["not_caused_detected_glitch"] += 1
                    else:
                        c["not_caused_detected_nothing_planted"] += 1
    return out


def fluent_clause_scores(n_passages: int, base_params) -> dict:
    """Clause starts (all but the first of a passage) on fluent synthetic speech (``data/fluent.py``:
    clauses joined without any pause, F0 resets and final lengthening only; passages of 7 clauses),
    precision and recall within :data:`CLAUSE_TOLERANCE_S`, words per clause, for the configured clause
    method and for ``pause``. ``base_params``: AnnotateParams."""
    from ..annotate.audio import annotate_audio
    from ..data.fluent import fluent_speech

    out = {}
    for method in (base_params.clause_method, "pause"):
        p = dataclasses.replace(base_params, clause_method=method)
        hp = n_p = hd = n_d = 0
        nw, peak_err = [], []
        for k in range(n_passages):
            rng = np.random.default_rng(1000 + k)
            sizes = [int(np.clip(round(rng.normal(4.1, 2.0)), 1, 10)) for _ in range(7)]
            audio, w, segs = fluent_speech(2000 + k, sizes, f0_base=(210.0, 118.0)[k % 2])
            seg = annotate_audio(w, audio, p)
            pc = seg[seg.kind == "PC"]
            truth, det = np.array([x.start for x in segs[1:]]), pc.start.to_numpy()[1:]
            hp += int(near(truth, det, CLAUSE_TOLERANCE_S).sum())
            n_p += truth.size
            hd += int(near(det, truth, CLAUSE_TOLERANCE_S).sum())
            n_d += det.size
            nw += pc.text.str.split().str.len().tolist()
            for x in segs:
                same = pc[(np.abs(pc.start - x.start) < CLAUSE_TOLERANCE_S) & (np.abs(pc.end - x.end) < CLAUSE_TOLERANCE_S)]
                if len(same):
                    peak_err.append(abs(float(same.peak.iloc[0]) - x.peak))
        out[method] = {"passages": n_passages, "boundary_recall": hp / max(n_p, 1),
                       "boundary_precision": hd / max(n_d, 1), "planted_boundaries": n_p, "detected_boundaries": n_d,
                       "words_per_clause": words_stats(nw),
                       "peak_within_0.1s_of_planted": float(np.mean(np.array(peak_err) < 0.1)) if peak_err else None}
    return out


def real_speech_scores(d: Path, params, names=("acoustic_corpus", "cold_corpus")) -> dict:
    """The audio annotation on real recordings ``d/<name>.wav`` with word TextGrids: words per clause,
    fillers labelled HP, HP on words outside the hesitation list, F0 median and peak range, octave-guard
    drops and suspicious peaks; ``{"skipped": ...}`` when ``d`` is not there. ``params``: AnnotateParams."""
    from ..annotate.audio import annotate_audio, f0_track, load_word_corpus, normalize_word
    from ..annotate.clauses import guard_f0
    from ..io import load_audio, load_transcript

    d = Path(d)
    if not d.is_dir():
        return {"skipped": f"{d} not found"}
    hesitation = set(load_word_corpus()["hesitation"])
    out = {}
    for name in names:
        w = load_transcript(d / f"{name}.TextGrid")
        audio = load_audio(d / f"{name}.wav")
        seg = annotate_audio(w, audio, params)
        fillers = w[w["word"].str.lower().isin(["uh", "um", "yknow"])]
        hp = seg[seg.kind == "HP"]
        in_hp = sum(((hp.start <= f.start + 1e-9) & (hp.end >= f.end - 1e-9)).any() for f in fillers.itertuples())
        hp_content = [t for t in hp.text if " ".join(normalize_word(x) for x in t.split()) not in hesitation]
        t, f = f0_track(audio, params)
        g = guard_f0(t, f, params)
        f0 = seg["f0_peak"].dropna()
        pc = seg[seg.kind == "PC"]
        out[name] = {"words": int(len(w)), "segments": seg["kind"].value_counts().to_dict(),
                     "words_per_clause": words_stats(pc.text.str.split().str.len()),
                     "clauses": pc.text.tolist(),
                     "fillers": int(len(fillers)), "fillers_labelled_hp": int(in_hp),
                     "hp_on_words_outside_the_hesitation_list": hp_content,
                     "f0_median_hz": g.median, "f0_frames_dropped_by_guard": int(g.dropped.sum()),
                     "f0_raw_max_hz": float(np.nanmax(g.raw)),
                     "f0_peak_hz_min": float(f0.min()), "f0_peak_hz_median": float(f0.median()),
                     "f0_peak_hz_max": float(f0.max()), "voiced_segments": int(len(f0)),
                     "suspicious_peaks": int(seg["f0_suspect"].sum()),
                     "peaks_inside_segments": bool(((seg.peak >= seg.start) & (seg.peak <= seg.end)).all())}
    return out
