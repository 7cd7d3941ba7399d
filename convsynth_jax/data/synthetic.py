"""Synthetic dyadic conversation corpus: the embedded default dataset.

Writes the same files a real corpus has (GENEA 2023 dyadic layout) plus the planted ground truth:

* ``<session>_main-agent.{bvh,wav,tsv}`` and ``<session>_interloctr.{bvh,wav,tsv}``;
* ``events.csv`` (session, participant, kind, start, peak, end) with every planted audio segment
  (PC, LR, HP) and motion event (LH, RH, Nod; a two-handed gesture is one LH and one RH row);
* ``corpus.json`` with the generator parameters, their hash and the characters.

The process: turn-taking between two seated people; a turn is a run of phonemic clauses (words per
clause drawn around each character's mean and spread) separated by short pauses, with hesitations
inside turns; the listener gives listener responses near clause ends. Audio is a harmonic voice
through two formant resonators with an F0 contour per clause (declination plus a pitch accent on the
stressed word, which is the clause's F0 peak). Motion is idle (breathing, slow drift, small noise)
plus hand gestures (preparation, stroke near the F0 peak, retraction) and nods, planted with the
configured co-occurrence probabilities (default: the paper's Table 1) and a small spontaneous rate.
"""
from __future__ import annotations

import copy
import hashlib
import json
import logging
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import signal

from ..errors import ConfigError
from ..io.audio import save_wav
from ..io.bvh import save_bvh
from ..io.transcripts import save_transcript_tsv
from ..rotations import euler_deg_to_quat_np, quat_multiply_np, yaw_to_quat_np
from ..skeleton import Motion
from ..utils import _umask
from .skeleton_seated import INDEX, NAMES, SEAT_HEIGHT, base_pose_degrees, seated_skeleton

log = logging.getLogger(__name__)

ROLES = ("main-agent", "interloctr")
EMOTIONS = {  # motion energy, speech rate
    "happy": (1.0, 1.0), "sad": (0.7, 0.85), "angry": (1.25, 1.1), "excited": (1.35, 1.2), "nervous": (0.85, 1.15),
}
VOCAB = ("we", "went", "there", "last", "summer", "and", "it", "was", "really", "nice", "you", "should",
         "have", "seen", "the", "place", "people", "were", "talking", "about", "work", "my", "friend",
         "said", "that", "would", "never", "happen", "again", "but", "then", "something", "changed",
         "school", "years", "ago", "remember", "when", "interview", "job", "money", "home", "city")
HESITATIONS = ("uh", "um", "er", "you know", "well")
RESPONSES = ("yeah", "uh-huh", "mm-hmm", "right", "I see", "wow", "okay")

DEFAULTS: dict = {
    "seed": 0,
    "num_sessions": 17,
    "session_seconds": 106.0,
    "fps": 30,
    "sample_rate": 16000,
    "write_audio": True,
    "characters": {
        "main-agent": {"name": "female", "words_mean": 4.29, "words_sd": 2.16, "f0": 210.0, "scale": 0.94,
                       "p_pc_lh": 0.62, "p_pc_rh": 0.65, "p_pc_either": 0.75, "p_lr_nod": 0.58, "p_ph_nod": 0.30},
        "interloctr": {"name": "male", "words_mean": 3.86, "words_sd": 1.36, "f0": 118.0, "scale": 1.0,
                       "p_pc_lh": 0.51, "p_pc_rh": 0.50, "p_pc_either": 0.62, "p_lr_nod": 0.53, "p_ph_nod": 0.35},
    },
    "clauses_per_turn": 3.0,      # mean (1 + Poisson(mean - 1))
    "p_hesitation": 0.3,          # chance of a hesitation before each clause after the first in a turn
    "p_listener_response": 0.45,  # chance the listener responds after a clause end
    "spontaneous_per_minute": 2.0,  # gestures/nods per minute of time away from the own candidate windows
    "word_seconds": [0.20, 0.34],
    "word_gap": [0.03, 0.07],
    "clause_pause": [0.45, 0.8],
    "turn_gap": [0.5, 1.0],
    "accent_rise": 0.28,          # relative F0 rise of the pitch accent
    "posture_sd": 1.5,            # degrees: per-session posture offset of spine, neck, head and arms
    "drift_sd": 1.5,              # degrees: slow posture drift (about 10 s correlation time)
    "min_event_gap": 0.3,         # seconds of idle between consecutive events of the same hand / the head
}
# bumped whenever the generator's output changes for the same parameters (part of the parameter hash)
GENERATOR_VERSION = 2


def _merge(base: dict, over) -> dict:
    out = copy.deepcopy(base)
    if over is None:
        return out
    try:
        from omegaconf import DictConfig, OmegaConf

        if isinstance(over, DictConfig):
            over = OmegaConf.to_container(over, resolve=True)
    except ImportError:  # pragma: no cover
        pass
    for k, v in dict(over).items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = _merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def resolve_config(config=None) -> dict:
    cfg = _merge(DEFAULTS, config)
    for role, c in cfg["characters"].items():
        lh, rh, either = c["p_pc_lh"], c["p_pc_rh"], c["p_pc_either"]
        if not (max(lh, rh) <= either <= min(1.0, lh + rh)):
            raise ConfigError(f"characters.{role}: need max(p_pc_lh, p_pc_rh) <= p_pc_either <= p_pc_lh + p_pc_rh")
    if cfg["num_sessions"] < 1 or cfg["session_seconds"] < 10:
        raise ConfigError("need at least one session of at least 10 s")
    return cfg


def config_hash(cfg: dict) -> str:
    """Hash of the resolved parameters and the generator version (a cached corpus is reused only if
    it matches)."""
    blob = json.dumps({"generator_version": GENERATOR_VERSION, "config": cfg}, sort_keys=True)
    return hashlib.sha1(blob.encode()).hexdigest()[:16]


# ----------------------------------------------------------------------------- conversation


@dataclass
class Segment:
    role: str
    kind: str  # PC, LR, HP
    start: float
    end: float
    peak: float
    words: list  # (start, end, word, stressed)


def _conversation(rng: np.random.Generator, cfg: dict, duration: float, rate: float) -> list[Segment]:
    """Audio segments of both participants for one session."""
    u = lambda lo_hi: rng.uniform(*lo_hi)  # noqa: E731
    segs: list[Segment] = []
    t = rng.uniform(0.5, 1.5)
    speaker = int(rng.integers(2))
    end_limit = duration - 1.5
    while t < end_limit:
        role, other = ROLES[speaker], ROLES[1 - speaker]
        ch = cfg["characters"][role]
        n_clauses = 1 + rng.poisson(max(cfg["clauses_per_turn"] - 1, 0))
        for c in range(n_clauses):
            if c > 0 and rng.random() < cfg["p_hesitation"]:
                word = HESITATIONS[rng.integers(len(HESITATIONS))]
                d = rng.uniform(0.3, 0.5) / rate
                if t + d > end_limit:
                    break
                segs.append(Segment(role, "HP", t, t + d, t + d / 2, [(t, t + d, word, False)]))
                t += d + u(cfg["clause_pause"]) / rate
            n_words = int(np.clip(np.round(rng.normal(ch["words_mean"], ch["words_sd"])), 1, 10))
            words = []
            w0 = t
            for _ in range(n_words):
                d = u(cfg["word_seconds"]) / rate
                words.append([t, t + d, VOCAB[rng.integers(len(VOCAB))], False])
                t += d + u(cfg["word_gap"])
            t -= words and (t - words[-1][1])  # no gap after the last word
            if t > end_limit:
                break
            k = int(rng.integers(n_words))
            words[k][3] = True
            peak = 0.5 * (words[k][0] + words[k][1])
            segs.append(Segment(role, "PC", w0, t, peak, [tuple(w) for w in words]))
            pause = u(cfg["clause_pause"]) / rate
            if rng.random() < cfg["p_listener_response"]:
                ls = t + rng.uniform(0.05, 0.25)
                d = rng.uniform(0.3, 0.55)
                word = RESPONSES[rng.integers(len(RESPONSES))]
                segs.append(Segment(other, "LR", ls, ls + d, ls + d / 2, [(ls, ls + d, word, False)]))
                pause = max(pause, ls + d + 0.4 - t)
            t += pause
        t += u(cfg["turn_gap"])
        speaker = 1 - speaker
    segs.sort(key=lambda s: (s.start, s.role))
    return segs


# ----------------------------------------------------------------------------- audio


def _render_voice(segs: list[Segment], f0_base: float, duration: float, sr: int, rng: np.random.Generator,
                  accent_rise: float):
    """Signal (N,) and the planted F0 track (N,) (0 where unvoiced) of one participant."""
    n = int(round(duration * sr))
    f0 = np.zeros(n)
    env = np.zeros(n)
    for s in segs:
        s0, s1 = s.words[0][0], s.words[-1][1]
        for (w0, w1, _, stressed) in s.words:
            a, b = int(w0 * sr), min(int(w1 * sr), n)
            if b <= a:
                continue
            tt = np.arange(a, b) / sr
            rel = (tt - s0) / max(s1 - s0, 1e-3)
            if s.kind == "PC":
                contour = f0_base * (1.08 - 0.16 * rel)  # declination across the clause
                contour = contour * (1.0 + accent_rise * np.exp(-0.5 * ((tt - s.peak) / 0.07) ** 2))
            else:
                contour = f0_base * (0.92 + 0.06 * np.exp(-0.5 * ((tt - s.peak) / 0.1) ** 2))
            f0[a:b] = contour
            ramp = min(int(0.02 * sr), (b - a) // 2)
            e = np.ones(b - a)
            if ramp > 0:
                e[:ramp] = np.linspace(0, 1, ramp)
                e[-ramp:] = np.linspace(1, 0, ramp)
            env[a:b] = e * (1.0 if (s.kind != "PC" or stressed) else 0.75)
    voiced = np.flatnonzero(env > 0)
    out = rng.normal(0.0, 0.002, n)
    if voiced.size:
        phase = 2 * np.pi * np.cumsum(f0) / sr
        ph = phase[voiced]
        src = np.zeros(voiced.size)
        for h in range(1, 13):
            src += np.sin(h * ph) / h
        voice = np.zeros(n)
        voice[voiced] = src * env[voiced]
        for fc, bw in ((600.0, 120.0), (1500.0, 200.0)):  # two formant resonators
            r = np.exp(-np.pi * bw / sr)
            th = 2 * np.pi * fc / sr
            voice = voice + 0.5 * signal.lfilter([1 - r], [1, -2 * r * np.cos(th), r * r], voice)
        voice *= 0.25 / max(np.abs(voice).max(), 1e-9)
        out += voice
    return out, f0


# ----------------------------------------------------------------------------- motion


def _smooth_noise(rng, n, fps, seconds, sd):
    """Low-pass Gaussian noise with a correlation time of about ``seconds``."""
    x = rng.normal(0, 1, n + int(4 * seconds * fps))
    k = max(1, int(seconds * fps))
    ker = np.hanning(2 * k + 1)
    y = np.convolve(x, ker / ker.sum(), mode="same")[: n]
    return sd * y / max(y.std(), 1e-9)


def _bump(t, start, end):
    """Smooth 0 -> 1 -> 0 profile over [start, end] (preparation, hold around the middle, retraction)."""
    x = np.clip((t - start) / max(end - start, 1e-3), 0, 1)
    return np.sin(np.pi * x) ** 2


POSTURE_JOINTS = ("Spine", "Spine1", "Neck", "Head", "LeftArm", "RightArm", "LeftForeArm", "RightForeArm",
                  "LeftHand", "RightHand")


def _motion(rng, role: str, events: list[dict], n: int, fps: float, energy: float, scale: float,
            posture_sd: float = 1.5, drift_sd: float = 1.5) -> Motion:
    skel = seated_skeleton(scale)
    t = np.arange(n) / fps
    euler = np.broadcast_to(base_pose_degrees(), (n, len(NAMES), 3)).copy()  # (F, J, [Z, X, Y])
    # people sit differently from one conversation to the next, and shift their posture slowly
    for j in POSTURE_JOINTS:
        euler[:, INDEX[j]] += rng.normal(0, posture_sd, 3)
        for c in range(3):
            euler[:, INDEX[j], c] += _smooth_noise(rng, n, fps, 10.0, drift_sd)
    # idle: breathing on the spine chain, slow posture drift, small noise everywhere
    breath = np.sin(2 * np.pi * t / rng.uniform(3.5, 4.5) + rng.uniform(0, 6.3))
    for j, a in (("Spine", 0.8), ("Spine1", 0.6), ("Spine2", 0.5)):
        euler[:, INDEX[j], 1] += a * breath
    for j in POSTURE_JOINTS[:8]:
        for c in range(3):
            euler[:, INDEX[j], c] += _smooth_noise(rng, n, fps, 2.0, 0.6)
    euler += rng.normal(0, 0.03, euler.shape)
    for ev in events:
        s, p, e, amp = ev["start"], ev["peak"], ev["end"], ev["amp"] * energy
        b = _bump(t, s, e)
        beat = np.exp(-0.5 * ((t - p) / 0.09) ** 2) * (np.abs(t - p) < 0.4)
        if ev["kind"] in ("LH", "RH"):
            side = "Left" if ev["kind"] == "LH" else "Right"
            sgn = 1.0 if side == "Left" else -1.0
            euler[:, INDEX[f"{side}Arm"], 1] -= amp * (22.0 * b + 6.0 * beat)
            euler[:, INDEX[f"{side}Arm"], 0] += sgn * amp * ev["spread"] * b
            euler[:, INDEX[f"{side}ForeArm"], 1] -= amp * (18.0 * b + 10.0 * beat)
            euler[:, INDEX[f"{side}Hand"], 1] += amp * 12.0 * beat
        else:  # nod: head pitch oscillation, 1-3 cycles, with a little neck
            cyc = ev["cycles"]
            x = np.clip((t - s) / max(e - s, 1e-3), 0, 1)
            osc = np.sin(2 * np.pi * cyc * x) * np.sin(np.pi * x) * ((t >= s) & (t <= e))
            euler[:, INDEX["Head"], 1] += amp * 11.0 * osc
            euler[:, INDEX["Neck"], 1] += amp * 3.0 * osc
    quats = euler_deg_to_quat_np(euler, "ZXY")
    trans = np.broadcast_to(skel.offsets, (n, len(NAMES), 3)).copy()
    z0 = -60.0 if role == ROLES[0] else 60.0
    trans[:, 0] = (0.0, SEAT_HEIGHT, z0)
    trans[:, 0, 0] += _smooth_noise(rng, n, fps, 6.0, 0.8)
    trans[:, 0, 2] += _smooth_noise(rng, n, fps, 6.0, 0.8)
    trans[:, 0, 1] += 0.3 * breath
    if role == ROLES[1]:  # the interlocutor faces the other way (-Z)
        quats[:, 0] = quat_multiply_np(yaw_to_quat_np(np.pi), quats[:, 0])
    return Motion(skel, quats, trans, float(fps), role)


def _plant_events(rng, segs: list[Segment], role: str, partner: str, cfg: dict,
                  duration: float) -> tuple[list[dict], float]:
    """Motion events of ``role`` planted around its own PCs and LRs and the partner's HPs, plus
    spontaneous ones away from those windows. Returns (events sorted by start, seconds of time
    available to spontaneous movements)."""
    ch = cfg["characters"][role]
    p_both = ch["p_pc_lh"] + ch["p_pc_rh"] - ch["p_pc_either"]
    p_lh_only = ch["p_pc_either"] - ch["p_pc_rh"]
    p_rh_only = ch["p_pc_either"] - ch["p_pc_lh"]
    events = []

    def gesture(kind, seg, amp):
        dur = float(np.clip(seg.end - seg.start, 0.6, 1.5))
        peak = seg.peak + rng.normal(0, 0.05)
        start = max(seg.start - 0.1, peak - 0.45 * dur)
        end = start + dur
        return {"kind": kind, "start": start, "peak": peak, "end": end, "amp": amp,
                "spread": rng.uniform(-8, 14), "source": seg.kind, "cause_start": seg.start}

    for seg in segs:
        if seg.role == role and seg.kind == "PC":
            u = rng.random()
            amp = rng.uniform(0.75, 1.25)
            if u < p_both:
                events += [gesture("LH", seg, amp), gesture("RH", seg, amp)]
            elif u < p_both + p_lh_only:
                events.append(gesture("LH", seg, amp))
            elif u < p_both + p_lh_only + p_rh_only:
                events.append(gesture("RH", seg, amp))
        elif (seg.role == role and seg.kind == "LR" and rng.random() < ch["p_lr_nod"]) or \
                (seg.role == partner and seg.kind == "HP" and rng.random() < ch["p_ph_nod"]):
            dur = float(np.clip(seg.end - seg.start + rng.uniform(0.1, 0.3), 0.45, 1.0))
            mid = 0.5 * (seg.start + seg.end) + rng.normal(0, 0.04)
            events.append({"kind": "Nod", "start": mid - dur / 2, "peak": mid, "end": mid + dur / 2,
                           "amp": rng.uniform(0.8, 1.2), "cycles": int(rng.integers(1, 4)), "source": seg.kind,
                           "cause_start": seg.start})
    events = _separate(events, cfg["min_event_gap"])
    # spontaneous movements: a Poisson process on the time away from this participant's candidate
    # windows (its own segments and the partner's hesitations) and away from its caused events
    sp_rng = np.random.default_rng(rng.integers(2 ** 63))
    busy = [_window(s) for s in segs if s.role == role or (s.role == partner and s.kind == "HP")]
    busy += [(e["start"] - SPONTANEOUS_MARGIN, e["end"] + SPONTANEOUS_MARGIN) for e in events]
    free = _free_intervals(busy, 1.0, duration - 1.5)
    free_seconds = float(sum(b - a for a, b in free))
    n_sp = sp_rng.poisson(cfg["spontaneous_per_minute"] * free_seconds / 60.0)
    for _ in range(n_sp):
        dur = sp_rng.uniform(0.6, 1.1)
        room = np.array([max(b - a - dur, 0.0) for a, b in free])
        if room.sum() <= 0:
            log.debug("%s: no room left for spontaneous movements", role)
            break
        i = int(sp_rng.choice(len(free), p=room / room.sum()))
        start = free[i][0] + sp_rng.uniform(0, room[i])
        kind = ("LH", "RH", "Nod")[sp_rng.integers(3)]
        events.append({"kind": kind, "start": start, "peak": start + dur / 2, "end": start + dur,
                       "amp": sp_rng.uniform(0.7, 1.1), "spread": sp_rng.uniform(-8, 14),
                       "cycles": int(sp_rng.integers(1, 3)), "source": "spontaneous"})
        a, b = free.pop(i)
        free[i:i] = [iv for iv in ((a, start - SPONTANEOUS_MARGIN), (start + dur + SPONTANEOUS_MARGIN, b)) if iv[1] > iv[0]]
    events.sort(key=lambda e: e["start"])
    return [e for e in events if e["start"] > 0.05 and e["end"] < duration - 0.05], free_seconds


SPONTANEOUS_MARGIN = 0.4  # seconds of idle kept between a spontaneous movement and any other event or window


def _window(seg: Segment) -> tuple[float, float]:
    """The candidate window of an audio segment (paper Fig. 3): twice its length around its centre."""
    half = 0.5 * (seg.end - seg.start)
    return seg.start - half, seg.end + half


def _free_intervals(busy: list[tuple[float, float]], lo: float, hi: float) -> list[tuple[float, float]]:
    """Sorted disjoint intervals of [lo, hi] not covered by any interval in ``busy``."""
    free, t = [], lo
    for a, b in sorted(busy):
        if a > t:
            free.append((t, min(a, hi)))
        t = max(t, b)
        if t >= hi:
            break
    if t < hi:
        free.append((t, hi))
    return [(a, b) for a, b in free if b > a]


def _separate(events: list[dict], gap: float, min_half: float = 0.15) -> list[dict]:
    """Keep ``gap`` seconds of idle between consecutive events of the same channel (LH, RH, Nod):
    where two would come closer, the earlier one ends and the later one starts earlier/later around
    their midpoint; if that leaves less than ``min_half`` seconds between an event's peak and its
    edge, the later event is dropped (rare: peaks of consecutive clauses are over 0.5 s apart)."""
    out = []
    for kind in ("LH", "RH", "Nod"):
        prev = None
        for e in sorted((e for e in events if e["kind"] == kind), key=lambda e: e["start"]):
            e = dict(e)
            if prev is not None and e["start"] < prev["end"] + gap:
                mid = 0.5 * (prev["end"] + e["start"])
                new_end, new_start = mid - gap / 2, mid + gap / 2
                if new_end - prev["peak"] < min_half or e["peak"] - new_start < min_half:
                    log.debug("dropping a %s event at %.2f s too close to the previous one", kind, e["start"])
                    continue
                prev["end"], e["start"] = new_end, new_start
            out.append(e)
            prev = e
    return sorted(out, key=lambda e: e["start"])


# ----------------------------------------------------------------------------- corpus


def _session(idx: int, cfg: dict, out: Path) -> tuple[list[dict], dict]:
    rng = np.random.default_rng([int(cfg["seed"]), idx])
    name = f"session{idx + 1:02d}"
    emotion = list(EMOTIONS)[int(rng.integers(len(EMOTIONS)))]
    energy, rate = EMOTIONS[emotion]
    duration = float(cfg["session_seconds"])
    fps, sr = float(cfg["fps"]), int(cfg["sample_rate"])
    n = int(round(duration * fps))
    segs = _conversation(rng, cfg, duration, rate)
    rows, free_seconds = [], {}
    for k, role in enumerate(ROLES):
        partner = ROLES[1 - k]
        ch = cfg["characters"][role]
        own = [s for s in segs if s.role == role]
        events, free_seconds[role] = _plant_events(rng, segs, role, partner, cfg, duration)
        motion = _motion(rng, role, events, n, fps, energy, ch["scale"], cfg["posture_sd"], cfg["drift_sd"])
        save_bvh(motion, out / f"{name}_{role}.bvh", precision=4)
        words = [(w[0], w[1], w[2]) for s in own for w in s.words]
        save_transcript_tsv(pd.DataFrame(words, columns=["start", "end", "word"]), out / f"{name}_{role}.tsv")
        if cfg["write_audio"]:
            sig, _ = _render_voice(own, ch["f0"], duration, sr, rng, cfg["accent_rise"])
            save_wav(out / f"{name}_{role}.wav", sig, sr)
        for s in own:
            rows.append({"session": name, "participant": role, "kind": s.kind, "start": s.start, "peak": s.peak,
                         "end": s.end, "text": " ".join(w[2] for w in s.words), "source": "", "cause_start": np.nan})
        for e in events:
            rows.append({"session": name, "participant": role, "kind": e["kind"], "start": e["start"],
                         "peak": e["peak"], "end": e["end"], "text": "", "source": e["source"],
                         "cause_start": e.get("cause_start", np.nan)})
    return rows, {"name": name, "emotion": emotion, "duration": duration,
                  "spontaneous_free_seconds": {r: round(v, 4) for r, v in free_seconds.items()}}


def make_synthetic_corpus(out_dir: str | Path, config=None) -> Path:
    """Write the synthetic corpus into ``out_dir`` (replaced atomically). Same seed, same bytes."""
    cfg = resolve_config(config)
    out_dir = Path(out_dir)
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.", dir=out_dir.parent))
    try:
        rows, sessions = [], []
        for i in range(int(cfg["num_sessions"])):
            r, meta = _session(i, cfg, tmp)
            rows += r
            sessions.append(meta)
        ev = pd.DataFrame(rows).round({"start": 4, "peak": 4, "end": 4, "cause_start": 4})
        ev.to_csv(tmp / "events.csv", index=False, float_format="%.4f")
        meta = {"generator": "convsynth_jax.data.synthetic", "generator_version": GENERATOR_VERSION,
                "seed": int(cfg["seed"]), "config": cfg, "config_hash": config_hash(cfg),
                "characters": {r: cfg["characters"][r]["name"] for r in ROLES}, "sessions": sessions}
        (tmp / "corpus.json").write_text(json.dumps(meta, indent=2, sort_keys=True) + "\n")
        os.chmod(tmp, 0o777 & ~_umask())
        if out_dir.exists():
            shutil.rmtree(out_dir)
        os.replace(tmp, out_dir)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    log.info("wrote synthetic corpus %s (%d sessions)", out_dir, len(sessions))
    return out_dir


def ensure_synthetic_corpus(corpus_cfg, cache_dir) -> Path:
    """The synthetic corpus of ``corpus_cfg``: reuse it if present with the same parameters, else
    generate it. Location: ``corpus_cfg.root`` or ``<cache_dir>/<corpus_cfg.name>``."""
    root = corpus_cfg.get("root") if hasattr(corpus_cfg, "get") else None
    root = Path(root) if root else Path(cache_dir) / str(corpus_cfg.get("name", "synthetic_default"))
    cfg = resolve_config(corpus_cfg.get("generator"))
    meta = root / "corpus.json"
    if meta.is_file():
        try:
            if json.loads(meta.read_text()).get("config_hash") == config_hash(cfg):
                return root
        except json.JSONDecodeError:
            pass
        log.info("synthetic corpus at %s has other parameters: regenerating", root)
    else:
        log.info("generating synthetic corpus into %s", root)
    return make_synthetic_corpus(root, cfg)
