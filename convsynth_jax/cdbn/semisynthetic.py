"""A semi-synthetic corpus for the CDBN (our construction, standing in for MSP-AVATAR's head gestures).

Turns of one speaker: phonemic clauses of words rendered with the synthetic corpus's voice
(``convsynth_jax.data.synthetic._render_voice``: harmonic source, formants, declination and a pitch
accent per clause), so the prosody features come from Praat on real-sounding audio. Head motion:

* *coupled to prosody* (constraint ``other``): pitch follows the smoothed, slightly lagged F0,
  yaw the smoothed energy envelope, plus slow noise on all three angles; the gains are chosen so that
  the CCA between the 6-D prosody and the head rotation is near the paper's 0.69;
* *nods* (constraint ``nod``, the span of one clause): the head pitches down during every word
  (-A sin(pi u), u the position inside the word), i.e. one nod per syllable-like word;
* *shakes* (constraint ``shake``): a full left-right yaw cycle per word (A sin(2 pi u)).
Gestures are locked to word boundaries, which the energy and its derivatives reveal, as nods are to
stressed syllables in real speech; the constraint decides pitch versus yaw.

Two subjects (different F0 and motion gains) exercise the per-subject z-normalization.
"""
from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from ..data.skeleton_seated import INDEX, NAMES, base_pose_degrees, seated_skeleton
from ..data.synthetic import VOCAB, Segment, _render_voice, _smooth_noise
from ..io.audio import save_wav
from ..io.bvh import save_bvh
from ..skeleton import Motion
from ..utils import atomic_path, write_json_atomic
from .params import SemiSyntheticParams

log = logging.getLogger(__name__)

CONSTRAINTS = ("other", "nod", "shake")


def _clauses(rng, duration: float) -> list[Segment]:
    segs, t = [], rng.uniform(0.3, 0.6)
    while t < duration - 1.2:
        words, w0 = [], t
        for _ in range(int(rng.integers(3, 8))):
            d = rng.uniform(0.2, 0.34)
            words.append([t, t + d, VOCAB[rng.integers(len(VOCAB))], False])
            t += d + rng.uniform(0.03, 0.07)
        t = words[-1][1]
        if t > duration - 0.3:
            break
        k = int(rng.integers(len(words)))
        words[k][3] = True
        segs.append(Segment("speaker", "PC", w0, t, 0.5 * (words[k][0] + words[k][1]), [tuple(w) for w in words]))
        t += rng.uniform(0.3, 0.6)
    return segs


def _z(x):
    return (x - x.mean()) / max(x.std(), 1e-9)


def make_turn(rng, p: SemiSyntheticParams, f0_base: float, gain: float):
    """(signal (N,), head angles (F, 3) pitch/yaw/roll degrees, constraint rows [(start, end, label)])."""
    duration = float(rng.uniform(*p.turn_seconds))
    segs = _clauses(rng, duration)
    sig, f0 = _render_voice(segs, f0_base, duration, p.sample_rate, rng, 0.28)
    n = round(duration * p.fps)
    t = np.arange(n) / p.fps
    hop = p.sample_rate / p.fps
    idx = np.minimum((np.arange(n) * hop).astype(int), len(f0) - 1)
    fr = f0[idx]
    voiced = fr > 0
    f_i = np.interp(t, t[voiced], fr[voiced]) if voiced.any() else np.zeros(n)
    win = int(0.04 * p.sample_rate)
    env = np.sqrt(np.convolve(sig ** 2, np.ones(win) / win, mode="same"))[idx]
    ker = np.hanning(9)
    ker /= ker.sum()
    lag = round(0.1 * p.fps)
    f_s = np.roll(np.convolve(_z(f_i), ker, mode="same"), lag)
    e_s = np.roll(np.convolve(_z(np.log(env + 1e-4)), ker, mode="same"), lag)
    pitch = gain * (p.pitch_gain * f_s + _smooth_noise(rng, n, p.fps, 1.0, p.noise_degrees))
    yaw = gain * (p.yaw_gain * e_s + _smooth_noise(rng, n, p.fps, 1.0, p.noise_degrees))
    roll = gain * _smooth_noise(rng, n, p.fps, 1.0, 0.6 * p.noise_degrees)
    rows = []
    k = int(rng.integers(p.gestures_per_turn[0], p.gestures_per_turn[1] + 1))
    chosen = rng.choice(len(segs), size=min(k, len(segs)), replace=False) if segs else []
    for ci in sorted(chosen):
        s = segs[ci]
        label = "nod" if rng.random() < p.p_nod else "shake"
        for (w0, w1, _, _) in s.words:
            m = (t >= w0) & (t < w1)
            u = (t[m] - w0) / (w1 - w0)
            if label == "nod":
                pitch[m] -= gain * p.nod_degrees * np.sin(np.pi * u)
            else:
                yaw[m] += gain * p.shake_degrees * np.sin(2 * np.pi * u)
        rows.append((s.start, s.end, label))
    return sig, np.stack([pitch, yaw, roll], axis=1), rows


def head_motion(angles: np.ndarray, fps: float, name: str) -> Motion:
    """A full seated-skeleton Motion whose Head joint carries the angles (pitch X, yaw Y, roll Z) on
    top of the neutral pose."""
    n = len(angles)
    skel = seated_skeleton(1.0)
    euler = np.broadcast_to(base_pose_degrees(), (n, len(NAMES), 3)).copy()
    euler[:, INDEX["Head"], 0] += angles[:, 2]
    euler[:, INDEX["Head"], 1] += angles[:, 0]
    euler[:, INDEX["Head"], 2] += angles[:, 1]
    quats = np.zeros((n, len(NAMES), 4))
    for j in range(len(NAMES)):
        quats[:, j] = Rotation.from_euler("ZXY", euler[:, j], degrees=True).as_quat()[:, [3, 0, 1, 2]]
    trans = np.broadcast_to(skel.offsets, (n, len(NAMES), 3)).copy()
    trans[:, 0] = (0.0, 48.0, 0.0)
    return Motion(skel, quats, trans, float(fps), name)


def make_semisynthetic_corpus(out_dir: str | Path, p: SemiSyntheticParams) -> dict:
    """Write ``turns/<turn>.{wav,bvh}``, ``turns/<turn>_constraints.tsv`` and ``corpus.json``."""
    out = Path(out_dir)
    (out / "turns").mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(p.seed)
    turns = []
    for i in range(p.num_turns):
        name, f0, gain = p.subjects[i % len(p.subjects)]
        sig, ang, rows = make_turn(rng, p, f0, gain)
        tid = f"turn{i:04d}"
        save_wav(out / "turns" / f"{tid}.wav", sig, p.sample_rate)
        save_bvh(head_motion(ang, p.fps, tid), out / "turns" / f"{tid}.bvh", precision=4)
        tsv = "start\tend\tlabel\n" + "".join(f"{a:.3f}\t{b:.3f}\t{lab}\n" for a, b, lab in rows)
        with atomic_path(out / "turns" / f"{tid}_constraints.tsv") as tmp:
            tmp.write_text(tsv)
        turns.append({"turn": tid, "subject": name, "seconds": len(ang) / p.fps,
                      "nod": sum(r[2] == "nod" for r in rows), "shake": sum(r[2] == "shake" for r in rows)})
    meta = {"generator": "convsynth_jax.cdbn.semisynthetic", "params": p.__dict__, "constraints": list(CONSTRAINTS),
            "turns": turns}
    write_json_atomic(out / "corpus.json", meta)
    df = pd.DataFrame(turns)
    return {"turns": len(turns), "seconds": float(df["seconds"].sum()), "nod_segments": int(df["nod"].sum()),
            "shake_segments": int(df["shake"].sum())}


def load_semisynthetic_corpus(root: str | Path) -> list[dict]:
    """[{turn, subject, wav, bvh, constraints}] of a corpus written by :func:`make_semisynthetic_corpus`."""
    from ..errors import CDBNError

    root = Path(root)
    meta_path = root / "corpus.json"
    if not meta_path.is_file():
        raise CDBNError("not a CDBN semi-synthetic corpus (no corpus.json); run convsynth task=cdbn_make_data",
                        meta_path)
    meta = json.loads(meta_path.read_text())
    return [{**t, "wav": root / "turns" / f"{t['turn']}.wav", "bvh": root / "turns" / f"{t['turn']}.bvh",
             "constraints": root / "turns" / f"{t['turn']}_constraints.tsv"} for t in meta["turns"]]


def ensure_corpus(root: str | Path, p: SemiSyntheticParams) -> Path:
    """The corpus at ``root``: reused when its corpus.json has the same parameters, else (re)written."""
    root = Path(root)
    meta = root / "corpus.json"
    if meta.is_file():
        try:
            old = json.loads(meta.read_text()).get("params")
            if json.loads(json.dumps(old)) == json.loads(json.dumps(p.__dict__)):
                return root
        except json.JSONDecodeError:
            pass
    make_semisynthetic_corpus(root, p)
    return root
