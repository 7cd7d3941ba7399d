"""Synthetic dyadic conversation corpus: the embedded default dataset.

Writes the same files a real corpus has (GENEA 2023 dyadic layout) plus the planted ground truth:

* ``<session>_main-agent.{bvh,wav,tsv}`` and ``<session>_interloctr.{bvh,wav,tsv}``;
* ``events.csv`` (session, participant, kind, start, peak, end) with every planted audio segment
  (PC, LR, HP) and motion event (LH, RH, Nod; a two-handed gesture is one LH and one RH row);
* ``glitches.csv`` (session, participant, kind, joint, channel, degrees, start_frame, end_frame) with
  every motion-capture glitch put into the BVH;
* ``corpus.json`` with the generator parameters, their hash, the characters and the calibration report.

The process: turn-taking between two seated people; a turn is a run of phonemic clauses (words per
clause drawn around each character's mean and spread), mostly joined without a pause (fluent
stretches whose clause boundaries show only as an F0 reset and pre-boundary lengthening), with
hesitations inside turns; the listener gives listener responses near clause ends, often over the end
of the clause, and turns may overlap. Audio is a harmonic voice through two formant resonators with an
F0 contour per clause (declination plus a pitch accent on the stressed word, which is the clause's
F0 peak). Motion is idle (breathing, slow drift, small noise) plus hand gestures (preparation,
stroke near the F0 peak, retraction; close same-hand gestures coarticulated, without rest between
them) and nods, planted so that the realized co-occurrence rates in the paper's windows match the
configured probabilities (default: the paper's Table 1; see ``planting_probabilities``), a small
spontaneous rate away from the windows, per-turn posture shifts, sensor noise and a few marker-swap
glitches (``glitches.csv``). Every difficulty has a parameter in ``DEFAULTS`` with an "off" value
(``conf/corpus/synthetic_tiny.yaml`` turns them all off).
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
from ..rotations import quat_multiply_np, yaw_to_quat_np
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
    "min_event_gap": 0.3,         # seconds of idle between consecutive events of the same head / of
                                  # the same hand when they are not coarticulated
    # --- difficulty knobs (what makes the corpus as hard as real data); each has an "off" value that
    # gives the easy corpus of generator version 2 in kind (not byte for byte)
    "p_clause_pause": 0.3,        # chance of a pause (clause_pause) between clauses of a turn; otherwise
                                  # the next clause follows after an ordinary word gap (off: 1.0)
    "final_lengthening": 1.3,     # the last word of a clause followed without pause is this much longer
                                  # (pre-boundary lengthening, a prosodic boundary cue; off: 1.0)
    "p_backchannel_overlap": 0.5,  # share of listener responses that start inside the speaker's clause,
                                  # 0.1-0.5 s before its end (overlapping speech; off: 0.0)
    "p_turn_overlap": 0.3,        # share of turn changes where the next speaker starts 0.1-0.6 s before
                                  # the previous one has finished (off: 0.0)
    "coarticulation_gap": 0.8,    # seconds: same-hand gestures whose idle gap would be shorter run into each
                                  # other: the first ends where the next starts and the hand is held, not
                                  # returned to rest, between the strokes (off: 0.0)
    "coarticulation_hold": [0.4, 0.8],  # held level between coarticulated gestures (share of amplitude)
    "sensor_noise_deg": 0.08,     # degrees: white measurement noise on every rotation channel (off: 0.03)
    "sensor_noise_cm": 0.08,      # cm: white measurement noise on the root position (off: 0.0)
    "glitches_per_minute": 0.5,   # marker-swap glitches per participant and minute (off: 0.0): for a few
                                  # frames the two arms swap (mirrored) or one joint jumps; listed in
                                  # glitches.csv, never in events.csv
    "glitch_frames": [2, 5],      # glitch length in frames (inclusive range)
    "posture_shift_sd": 3.7,      # degrees: before each of its turns a participant shifts to a new rest
                                  # posture (offset of spine, neck, head and arms), away from its candidate
                                  # windows (off: 0.0)
    "posture_shift_seconds": [0.6, 1.2],  # duration of a posture shift
    "calibrate_rates": True,      # plant with p' such that the realized window rates (other movements landing
                                  # in windows, movements lost to neighbours) match the configured ones, p'
                                  # measured on the corpus's own plan (see planting_probabilities; off: False)
    "calibrate_against": "detector",  # what measures the realized rates during calibration: "detector" (ours,
                                  # default) renders each pass's motion and counts with the annotation pipeline's
                                  # own speed detector and counter (stats.cooccurrence.hypothesis_matches on the
                                  # planted audio segments, default AnnotateParams), so Table 1 as the pipeline
                                  # measures it matches the configured rates; "windows" counts the planted
                                  # movement intervals with window_matches (no rendering, fast, but it treats a
                                  # movement that touches a window as used up to its end, which the detector
                                  # does not: it over-trims the next window, and a corpus calibrated that way
                                  # measures 5-11 points above the configured hand rates)
    "calibration_passes": 5,      # fixed-point passes of the calibration at most (the best one is kept)
    "calibration_tolerance": 0.01,  # stop the passes once every realized rate is this close to the configured one
    "quota_planting": True,       # plant exactly round(p * N) caused movements over the corpus (spread over
                                  # the sessions in proportion) instead of N independent Bernoulli(p) draws,
                                  # so realized rates carry no sampling error (off: False)
}
# bumped whenever the generator's output changes for the same parameters (part of the parameter hash)
GENERATOR_VERSION = 4


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
    unknown = sorted(set(cfg) - set(DEFAULTS))
    if unknown:
        raise ConfigError(f"corpus.generator: unknown key(s) {unknown}; known: {sorted(DEFAULTS)}")
    if cfg["calibrate_against"] not in CALIBRATION_MEASURES:
        raise ConfigError(f"corpus.generator.calibrate_against: {cfg['calibrate_against']!r}; expected one of "
                          f"{list(CALIBRATION_MEASURES)}")
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
    blob = {"generator_version": GENERATOR_VERSION, "config": cfg}
    if cfg.get("calibrate_rates") and cfg.get("calibrate_against") == "detector":
        blob["detector"] = detector_settings()  # the corpus depends on the detector it was calibrated with
    blob = json.dumps(blob, sort_keys=True)
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
    """Audio segments of both participants for one session.

    Turns alternate; a turn is a run of clauses, mostly joined without a pause (``p_clause_pause``),
    so a pause-free stretch holds several clauses whose boundaries show only in the prosody (F0 reset,
    pre-boundary lengthening). Listener responses may start inside the speaker's clause
    (``p_backchannel_overlap``) and the next turn may start before the previous one has ended
    (``p_turn_overlap``). One participant's own segments never overlap each other: a new segment of a
    participant starts at least ``SAME_SPEAKER_GAP`` after that participant's previous one."""
    u = lambda lo_hi: rng.uniform(*lo_hi)  # noqa: E731
    segs: list[Segment] = []
    busy = {r: -1.0 for r in ROLES}  # end of each participant's latest segment
    t = rng.uniform(0.5, 1.5)
    speaker = int(rng.integers(2))
    end_limit = duration - 1.5
    lengthen = float(cfg["final_lengthening"])
    stop = False
    while t < end_limit and not stop:
        role, other = ROLES[speaker], ROLES[1 - speaker]
        ch = cfg["characters"][role]
        n_clauses = 1 + rng.poisson(max(cfg["clauses_per_turn"] - 1, 0))
        for c in range(n_clauses):
            if c > 0 and rng.random() < cfg["p_hesitation"]:
                word = HESITATIONS[rng.integers(len(HESITATIONS))]
                d = rng.uniform(0.3, 0.5) / rate
                if t + d > end_limit:
                    stop = True
                    break
                segs.append(Segment(role, "HP", t, t + d, t + d / 2, [(t, t + d, word, False)]))
                busy[role] = t + d
                t += d + u(cfg["clause_pause"]) / rate  # a filler is followed by a pause
            n_words = int(np.clip(np.round(rng.normal(ch["words_mean"], ch["words_sd"])), 1, 10))
            last = c == n_clauses - 1
            fluent = not last and rng.random() >= cfg["p_clause_pause"]
            words = []
            w0 = t
            for i in range(n_words):
                d = u(cfg["word_seconds"]) / rate
                if fluent and i == n_words - 1:
                    d *= lengthen
                words.append([t, t + d, VOCAB[rng.integers(len(VOCAB))], False])
                t += d + u(cfg["word_gap"])
            t -= words and (t - words[-1][1])  # no gap after the last word
            if t > end_limit:
                stop = True
                break
            k = int(rng.integers(n_words))
            words[k][3] = True
            peak = 0.5 * (words[k][0] + words[k][1])
            segs.append(Segment(role, "PC", w0, t, peak, [tuple(w) for w in words]))
            busy[role] = t
            pause = u(cfg["clause_pause"]) / rate if not fluent else u(cfg["word_gap"])
            if rng.random() < cfg["p_listener_response"]:
                d = rng.uniform(0.3, 0.55)
                if rng.random() < cfg["p_backchannel_overlap"]:  # over the end of the clause
                    ls = max(t - rng.uniform(0.1, 0.5), w0 + 0.1)
                else:
                    ls = t + rng.uniform(0.05, 0.25)
                ls = max(ls, busy[other] + SAME_SPEAKER_GAP)
                word = RESPONSES[rng.integers(len(RESPONSES))]
                segs.append(Segment(other, "LR", ls, ls + d, ls + d / 2, [(ls, ls + d, word, False)]))
                busy[other] = ls + d
                if not fluent:  # a paused speaker waits for the response to end
                    pause = max(pause, ls + d + 0.4 - t)
            t += pause
        # the next speaker: after a gap, or (p_turn_overlap) before the current speaker has finished
        turn_end = busy[role]
        if rng.random() < cfg["p_turn_overlap"]:
            t_next = turn_end - rng.uniform(0.1, 0.6)
        else:
            t_next = turn_end + u(cfg["turn_gap"])
        speaker = 1 - speaker
        t = max(t_next, busy[ROLES[speaker]] + SAME_SPEAKER_GAP)
    segs.sort(key=lambda s: (s.start, s.role))
    return segs


SAME_SPEAKER_GAP = 0.35  # seconds between consecutive segments of one participant (at least)


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


def _envelope(t: np.ndarray, ev: dict) -> np.ndarray:
    """Gesture profile on [start, end): from ``hold_start`` (0 = rest) up to 1 at the middle, down to
    ``hold_end`` (levels relative to the event's amplitude; both 0 unless coarticulated), 0 outside.
    Without holds it is ``_bump``."""
    s, e = ev["start"], ev["end"]
    m = 0.5 * (s + e)
    h0 = ev.get("hold_start", 0.0) / ev["amp"]
    h1 = ev.get("hold_end", 0.0) / ev["amp"]
    rise = h0 + (1 - h0) * np.sin(0.5 * np.pi * np.clip((t - s) / max(m - s, 1e-3), 0, 1)) ** 2
    fall = h1 + (1 - h1) * np.sin(0.5 * np.pi * np.clip((e - t) / max(e - m, 1e-3), 0, 1)) ** 2
    return np.where(t < m, rise, fall) * ((t >= s) & (t < e))


def _posture_offsets(rng, n: int, fps: float, shifts: list[float], session_sd: float, shift_sd: float,
                     shift_seconds) -> np.ndarray:
    """(F, len(POSTURE_JOINTS), 3) degrees: the session's posture offset, replaced at each time in
    ``shifts`` by a new one (N(0, shift_sd) around the session's) over ``shift_seconds`` (smooth step)."""
    t = np.arange(n) / fps
    base = rng.normal(0, session_sd, (len(POSTURE_JOINTS), 3))
    off = np.broadcast_to(base, (n, len(POSTURE_JOINTS), 3)).copy()
    if shift_sd <= 0:
        return off
    cur = base
    for tau in shifts:
        new = base + rng.normal(0, shift_sd, base.shape)
        d = rng.uniform(*shift_seconds)
        x = np.clip((t - tau) / d, 0, 1)
        w = (x * x * (3 - 2 * x))[:, None, None]
        sel = t >= tau
        off[sel] = (cur + w * (new - cur))[sel]
        cur = new
    return off


GLITCH_JOINTS = ("LeftArm", "RightArm", "LeftForeArm", "RightForeArm", "LeftHand", "RightHand", "Neck", "Head")


def _glitches(rng, n: int, fps: float, per_minute: float, frames) -> list[dict]:
    """Marker-swap glitches of one participant: a Poisson number (``per_minute``) of few-frame
    artefacts, each either a ``flip`` (a forearm twists 90-180 degrees about its long axis, as when
    two markers of the segment swap labels) or a ``jump`` (one joint's rotation jumps 12-30 degrees
    about one axis, as when the solver snaps to a wrong marker). Rows: kind, joint, channel (0..2 of
    Z, X, Y), degrees, start_frame, end_frame (exclusive)."""
    count = rng.poisson(per_minute * n / fps / 60.0)
    out = []
    for _ in range(count):
        length = int(rng.integers(frames[0], frames[1] + 1))
        start = int(rng.integers(1, max(2, n - length - 1)))
        if rng.random() < 0.5:
            joint = ("LeftForeArm", "RightForeArm")[rng.integers(2)]
            out.append({"kind": "flip", "joint": joint, "channel": 2,
                        "degrees": float(rng.choice([-1, 1]) * rng.uniform(90, 180))})
        else:
            out.append({"kind": "jump", "joint": GLITCH_JOINTS[rng.integers(len(GLITCH_JOINTS))],
                        "channel": int(rng.integers(3)), "degrees": float(rng.choice([-1, 1]) * rng.uniform(12, 30))})
        out[-1].update(start_frame=start, end_frame=min(n, start + length))
    return sorted(out, key=lambda g: g["start_frame"])


def _zxy_deg_to_quat(euler: np.ndarray) -> np.ndarray:
    """(..., 3) BVH Euler angles in degrees, channel order Z X Y (intrinsic, Z outermost) -> (..., 4)
    (w, x, y, z) quaternions qz * qx * qy: the generator's fast path (about 30 times faster than
    SciPy's ``from_euler``, which ``rotations.euler_deg_to_quat_np`` uses and a test compares with)."""
    h = np.deg2rad(np.asarray(euler, np.float64)) / 2
    c, s = np.cos(h), np.sin(h)
    cz, cx, cy = c[..., 0], c[..., 1], c[..., 2]
    sz, sx, sy = s[..., 0], s[..., 1], s[..., 2]
    # qz * qx = (cz cx, cz sx, sz sx, sz cx), then times qy = (cy, 0, sy, 0)
    w, x, y, z = cz * cx, cz * sx, sz * sx, sz * cx
    return np.stack([w * cy - y * sy, x * cy - z * sy, w * sy + y * cy, z * cy + x * sy], axis=-1)


def _motion(rng, role: str, events: list[dict], n: int, fps: float, energy: float, scale: float,
            cfg: dict, shifts: list[float] = ()) -> tuple[Motion, list[dict]]:
    """The participant's motion and its glitches (see ``_glitches``)."""
    skel = seated_skeleton(scale)
    t = np.arange(n) / fps
    # streams of their own: the number of posture shifts (which follows the planted movements) does
    # not change the idle motion, the noise or the glitches
    posture_rng, glitch_rng, rng = (np.random.default_rng(rng.integers(2 ** 63)) for _ in range(3))
    euler = np.broadcast_to(base_pose_degrees(), (n, len(NAMES), 3)).copy()  # (F, J, [Z, X, Y])
    # people sit differently from one conversation to the next, shift their posture at their turns,
    # and drift slowly
    off = _posture_offsets(posture_rng, n, fps, list(shifts), cfg["posture_sd"], cfg["posture_shift_sd"],
                           cfg["posture_shift_seconds"])
    for i, j in enumerate(POSTURE_JOINTS):
        euler[:, INDEX[j]] += off[:, i]
        for c in range(3):
            euler[:, INDEX[j], c] += _smooth_noise(rng, n, fps, 10.0, cfg["drift_sd"])
    # idle: breathing on the spine chain, slow posture drift, small noise everywhere
    breath = np.sin(2 * np.pi * t / rng.uniform(3.5, 4.5) + rng.uniform(0, 6.3))
    for j, a in (("Spine", 0.8), ("Spine1", 0.6), ("Spine2", 0.5)):
        euler[:, INDEX[j], 1] += a * breath
    for j in POSTURE_JOINTS[:8]:
        for c in range(3):
            euler[:, INDEX[j], c] += _smooth_noise(rng, n, fps, 2.0, 0.6)
    euler += rng.normal(0, cfg["sensor_noise_deg"], euler.shape)
    for ev in events:
        s, p, e, amp = ev["start"], ev["peak"], ev["end"], ev["amp"] * energy
        beat = np.exp(-0.5 * ((t - p) / 0.09) ** 2) * (np.abs(t - p) < 0.4)
        if ev["kind"] in ("LH", "RH"):
            b = _envelope(t, ev)
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
    glitches = _glitches(glitch_rng, n, fps, cfg["glitches_per_minute"], cfg["glitch_frames"])
    for g in glitches:
        euler[g["start_frame"]:g["end_frame"], INDEX[g["joint"]], g["channel"]] += g["degrees"]
    quats = _zxy_deg_to_quat(euler)
    trans = np.broadcast_to(skel.offsets, (n, len(NAMES), 3)).copy()
    z0 = -60.0 if role == ROLES[0] else 60.0
    trans[:, 0] = (0.0, SEAT_HEIGHT, z0)
    trans[:, 0, 0] += _smooth_noise(rng, n, fps, 6.0, 0.8)
    trans[:, 0, 2] += _smooth_noise(rng, n, fps, 6.0, 0.8)
    trans[:, 0, 1] += 0.3 * breath
    if cfg["sensor_noise_cm"] > 0:
        trans[:, 0] += rng.normal(0, cfg["sensor_noise_cm"], (n, 3))
    if role == ROLES[1]:  # the interlocutor faces the other way (-Z)
        quats[:, 0] = quat_multiply_np(yaw_to_quat_np(np.pi), quats[:, 0])
    return Motion(skel, quats, trans, float(fps), role), glitches


def _plant_events(rng, segs: list[Segment], role: str, partner: str, cfg: dict,
                  duration: float, offsets: dict | None = None) -> tuple[list[dict], float]:
    """Motion events of ``role`` planted around its own PCs and LRs and the partner's HPs, plus
    spontaneous ones away from those windows. Returns (events sorted by start, seconds of time
    available to spontaneous movements)."""
    ch = cfg["characters"][role]
    p_both = ch["p_pc_lh"] + ch["p_pc_rh"] - ch["p_pc_either"]
    p_lh_only = ch["p_pc_either"] - ch["p_pc_rh"]
    p_rh_only = ch["p_pc_either"] - ch["p_pc_lh"]
    events = []
    # every random choice below draws from a stream of its own, and the attributes of a segment's
    # movement are drawn for every candidate segment whether it gets one or not, so planting with
    # other probabilities changes which segments cause a movement and nothing else (the calibration
    # compares corpora planted with nearby probabilities: its measure must not jump with the draws)
    st = {k: np.random.default_rng(rng.integers(2 ** 63))
          for k in ("attributes", "PC", "LR", "HP", "separate", "replant", "spontaneous")}
    pcs = [s for s in segs if s.role == role and s.kind == "PC"]
    lrs = [s for s in segs if s.role == role and s.kind == "LR"]
    hps = [s for s in segs if s.role == partner and s.kind == "HP"]
    a = st["attributes"]
    g_attr = {id(s): (a.uniform(0.75, 1.25), {k: (a.normal(0, 0.05), a.uniform(-8, 14)) for k in ("LH", "RH")})
              for s in pcs}
    n_attr = {id(s): (a.uniform(0.1, 0.3), a.normal(0, 0.04), a.uniform(0.8, 1.2), int(a.integers(1, 4)))
              for s in lrs + hps}

    def gesture(kind, seg):
        amp, hands = g_attr[id(seg)]
        jitter, spread = hands[kind]
        dur = float(np.clip(seg.end - seg.start, 0.6, 1.5))
        peak = seg.peak + jitter
        start = max(seg.start - 0.1, peak - 0.45 * dur)
        end = start + dur
        return {"kind": kind, "start": start, "peak": peak, "end": end, "amp": amp,
                "spread": spread, "source": seg.kind, "cause_start": seg.start}

    def nod(seg):
        extra, jitter, amp, cycles = n_attr[id(seg)]
        dur = float(np.clip(seg.end - seg.start + extra, 0.45, 1.0))
        mid = 0.5 * (seg.start + seg.end) + jitter
        return {"kind": "Nod", "start": mid - dur / 2, "peak": mid, "end": mid + dur / 2,
                "amp": amp, "cycles": cycles, "source": seg.kind, "cause_start": seg.start}

    # which segments cause a movement: per segment kind, a category per segment (PC: both hands, LH
    # only, RH only, none; LR / partner's HP: nod or none), either drawn independently or as an exact
    # quota (stochastic rounding of p * n, randomly assigned)
    quota = bool(cfg["quota_planting"])
    off = offsets or {}
    pc_cat = _categories(st["PC"], len(pcs), [p_both, p_lh_only, p_rh_only], quota, off.get("PC", 0))
    lr_nod = _categories(st["LR"], len(lrs), [ch["p_lr_nod"]], quota, off.get("LR", 0)) == 0
    hp_nod = _categories(st["HP"], len(hps), [ch["p_ph_nod"]], quota, off.get("HP", 0)) == 0
    causes = {id(s): c for s, c in zip(pcs, pc_cat)}
    causes.update({id(s): 0 if n else -1 for s, n in zip(lrs, lr_nod)})
    causes.update({id(s): 0 if n else -1 for s, n in zip(hps, hp_nod)})
    for seg in segs:
        cat = causes.get(id(seg), -1)
        if seg.kind == "PC" and seg.role == role:
            if cat in (0, 1):
                events.append(gesture("LH", seg))
            if cat in (0, 2):
                events.append(gesture("RH", seg))
        elif cat == 0:
            events.append(nod(seg))

    def settle(evs):
        evs = _separate(evs, cfg["min_event_gap"], cfg["coarticulation_gap"], cfg["coarticulation_hold"],
                        st["separate"])
        return [e for e in evs if e["start"] > 0.05 and e["end"] < duration - 0.05]

    events = settle(events)
    if quota:  # nods dropped for coming too close to another nod (or to the clip's edge) are replanted
        for _ in range(4):  # on other segments of the same kind, so the quota holds
            added = False
            for kind, pool, target in (("LR", lrs, int(lr_nod.sum())), ("HP", hps, int(hp_nod.sum()))):
                have = {e["cause_start"] for e in events if e["kind"] == "Nod" and e["source"] == kind}
                free = [sg for sg in pool if sg.start not in have]
                need = min(target - len(have), len(free))
                if need > 0:
                    events += [nod(free[i]) for i in st["replant"].choice(len(free), need, replace=False)]
                    added = True
            if not added:
                break
            events = settle(events)
    # spontaneous movements: a Poisson process on the time away from this participant's candidate
    # windows (its own segments and the partner's hesitations) and away from its caused events
    sp_rng = st["spontaneous"]
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


def _categories(rng: np.random.Generator, n: int, probs: list[float], quota: bool, offset: int = 0) -> np.ndarray:
    """A category per item: i with probability probs[i], len(probs) (none) with the rest. Independent
    draws, or (``quota``) exact counts of the cumulative probabilities P_i, assigned to the items in
    random order: the items continue a corpus-wide sequence after ``offset`` earlier ones (earlier
    sessions), and this session gets round(P_i (offset + n)) - round(P_i offset), so the corpus total
    is round(P_i N) however the items fall into sessions."""
    cum = np.cumsum(probs)
    if not quota:
        return np.searchsorted(cum, rng.random(n), side="right")
    bounds = np.floor(cum * (offset + n) + 0.5).astype(int) - np.floor(cum * offset + 0.5).astype(int)
    bounds = np.minimum(np.maximum.accumulate(np.maximum(bounds, 0)), n)
    cats = np.searchsorted(bounds, np.arange(n), side="right")
    return rng.permutation(cats)


def _separate(events: list[dict], gap: float, coarticulation_gap: float = 0.0, hold=(0.4, 0.8),
              rng: np.random.Generator | None = None, min_half: float = 0.15) -> list[dict]:
    """Keep ``gap`` seconds of idle between consecutive events of the same channel (LH, RH, Nod):
    where two would come closer, the earlier one ends and the later one starts earlier/later around
    their midpoint; if that leaves less than ``min_half`` seconds between an event's peak and its
    edge, the later event is dropped (rare: peaks of consecutive clauses are over 0.5 s apart).

    Hand gestures whose idle gap would be under ``coarticulation_gap`` are coarticulated instead: the
    earlier one ends exactly where the later one starts (between the peaks, at least ``min_half`` from
    each) and the hand is held at a level drawn from ``hold`` (share of the smaller amplitude) at that
    boundary instead of returning to rest (``hold_end`` of the earlier, ``hold_start`` of the later
    event, in absolute amplitude units); the later gesture keeps the earlier one's spread."""
    out = []
    for kind in ("LH", "RH", "Nod"):
        prev = None
        for e in sorted((e for e in events if e["kind"] == kind), key=lambda e: e["start"]):
            e = dict(e)
            if prev is not None and kind != "Nod" and coarticulation_gap > 0 \
                    and e["start"] < prev["end"] + coarticulation_gap:
                b = float(np.clip(0.5 * (prev["end"] + e["start"]), prev["peak"] + min_half, e["peak"] - min_half))
                if e["peak"] - prev["peak"] < 2 * min_half:
                    log.debug("dropping a %s event at %.2f s too close to the previous one", kind, e["start"])
                    continue
                level = float(rng.uniform(*hold)) * min(prev["amp"], e["amp"])
                prev["end"], e["start"] = b, b
                prev["hold_end"], e["hold_start"], e["spread"] = level, level, prev["spread"]
            elif prev is not None and e["start"] < prev["end"] + gap:
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


def _session_start(idx: int, cfg: dict):
    """(generator, emotion, conversation) of session ``idx``."""
    rng = np.random.default_rng([int(cfg["seed"]), idx])
    emotion = list(EMOTIONS)[int(rng.integers(len(EMOTIONS)))]
    segs = _conversation(rng, cfg, float(cfg["session_seconds"]), EMOTIONS[emotion][1])
    return rng, emotion, segs


def _quota_offsets(cfg: dict) -> list[dict]:
    """Per session, per role: how many of the role's PCs and LRs and of the partner's HPs the earlier
    sessions hold (the corpus-wide quota sequence of ``_categories``)."""
    out, tot = [], {r: {"PC": 0, "LR": 0, "HP": 0} for r in ROLES}
    for i in range(int(cfg["num_sessions"])):
        out.append({r: dict(v) for r, v in tot.items()})
        segs = _session_start(i, cfg)[2]
        for k, r in enumerate(ROLES):
            tot[r]["PC"] += sum(sg.role == r and sg.kind == "PC" for sg in segs)
            tot[r]["LR"] += sum(sg.role == r and sg.kind == "LR" for sg in segs)
            tot[r]["HP"] += sum(sg.role == ROLES[1 - k] and sg.kind == "HP" for sg in segs)
    return out


def _plan(idx: int, cfg: dict, probs: dict, offsets: list[dict] | None = None) -> dict:
    """Conversation and planted movements of session ``idx`` (no rendering); ``probs``: per role the
    planting probabilities (keys of HYPOTHESIS_KEYS); ``offsets``: ``_quota_offsets``. Rendering
    draws from streams of its own (``_render_rng``)."""
    rng, emotion, segs = _session_start(idx, cfg)
    energy = EMOTIONS[emotion][0]
    duration = float(cfg["session_seconds"])
    events, free_seconds = {}, {}
    for k, role in enumerate(ROLES):
        ch = {**cfg["characters"][role], **probs[role]}
        events[role], free_seconds[role] = _plant_events(rng, segs, role, ROLES[1 - k], {**cfg, "characters": {role: ch}},
                                                         duration, offsets[idx][role] if offsets else None)
    return {"index": idx, "name": f"session{idx + 1:02d}", "emotion": emotion, "energy": energy,
            "duration": duration, "segs": segs, "events": events, "free_seconds": free_seconds}


def _render_rng(cfg: dict, idx: int, role: str, what: str) -> np.random.Generator:
    """The generator of one participant's motion or audio in session ``idx``: a stream of its own, so
    the motion renders the same whether or not the audio is rendered (calibration renders motion only)."""
    return np.random.default_rng([int(cfg["seed"]), idx, ROLES.index(role), {"motion": 1, "audio": 2}[what]])


def _render_motion(plan: dict, role: str, cfg: dict) -> tuple[Motion, list[dict]]:
    """The motion of ``role`` in a planned session and its glitches (what gets written to its BVH)."""
    events = plan["events"][role]
    shifts = _shift_times(plan["segs"], role, events, plan["duration"], float(cfg["posture_shift_seconds"][1]))
    n = int(round(plan["duration"] * float(cfg["fps"])))
    return _motion(_render_rng(cfg, plan["index"], role, "motion"), role, events, n, float(cfg["fps"]),
                   plan["energy"], cfg["characters"][role]["scale"], cfg, shifts)


# hypothesis -> (audio kind, movement kinds, whose audio, configuration key); paper Table 1
HYPOTHESIS_KEYS = {"PC-LH": ("PC", ("LH",), "own", "p_pc_lh"), "PC-RH": ("PC", ("RH",), "own", "p_pc_rh"),
                   "PC-LH/RH": ("PC", ("LH", "RH"), "own", "p_pc_either"),
                   "LR-Nod": ("LR", ("Nod",), "own", "p_lr_nod"), "PH-Nod": ("HP", ("Nod",), "partner", "p_ph_nod")}
CORE = 0.0  # a movement counts on [start + CORE * length, end - CORE * length] (window matching; 0: all of it,
# which is what the annotation pipeline's nod detection reproduces on the default corpus)


def window_matches(audio: np.ndarray, channel: np.ndarray, movements: np.ndarray) -> np.ndarray:
    """Which audio segments co-occur with a movement, as the paper's windows see it (Figure 3).

    audio: (N, 2) [start, end] seconds of the hypothesis' audio segments; channel: (M, 2) every audio
    segment of that channel (the neighbours that trim a window); movements: (K, 2) [start, end] of the
    participant's movements of the hypothesis' kinds. A window is the segment doubled around its
    centre, trimmed to the neighbouring segments; windows are visited in time order and each starts
    no earlier than the end of the movement matched by the previous one; a window is matched when the
    core of a movement (``CORE``) overlaps it. Returns (N,) bool in the order of ``audio``."""
    audio, channel, movements = (np.asarray(x, float).reshape(-1, 2) for x in (audio, channel, movements))
    length = movements[:, 1] - movements[:, 0]
    core = np.stack([movements[:, 0] + CORE * length, movements[:, 1] - CORE * length], 1)
    out = np.zeros(len(audio), bool)
    last_end = -np.inf
    for i in np.argsort(audio[:, 0], kind="stable"):
        s, e = audio[i]
        lo, hi = s - (e - s) / 2, e + (e - s) / 2
        prev = channel[(channel[:, 1] <= s + 1e-9) & (channel[:, 0] < s - 1e-9), 1]
        nxt = channel[(channel[:, 0] >= e - 1e-9) & (channel[:, 1] > e + 1e-9), 0]
        lo = max(lo, prev.max()) if prev.size else lo
        hi = min(hi, nxt.min()) if nxt.size else hi
        lo = max(lo, last_end)
        hit = (core[:, 0] < hi) & (core[:, 1] > lo)
        if hi > lo and hit.any():
            out[i] = True
            last_end = movements[hit, 1].max()
    return out


def _plan_matches(plan: dict, role: str, hypothesis: str) -> tuple[np.ndarray, np.ndarray]:
    """(matched, caused) flags over the hypothesis' audio segments of one planned session, matched as
    ``window_matches`` sees the planted movement intervals (``calibrate_against="windows"``)."""
    akind, kinds, whose, _ = HYPOTHESIS_KEYS[hypothesis]
    owner = role if whose == "own" else ROLES[1 - ROLES.index(role)]
    chan = [sg for sg in plan["segs"] if sg.role == owner]
    audio = [sg for sg in chan if sg.kind == akind]
    evs = [e for e in plan["events"][role] if e["kind"] in kinds]
    m = window_matches([(a.start, a.end) for a in audio], [(c.start, c.end) for c in chan],
                       [(e["start"], e["end"]) for e in evs])
    return m, _caused(plan, role, hypothesis, audio)


def _caused(plan: dict, role: str, hypothesis: str, audio: list[Segment]) -> np.ndarray:
    """Which of the ``audio`` segments caused a movement of the hypothesis' kinds of ``role``."""
    akind, kinds, _, _ = HYPOTHESIS_KEYS[hypothesis]
    caused = {e.get("cause_start") for e in plan["events"][role] if e["kind"] in kinds and e["source"] == akind}
    return np.array([a.start in caused for a in audio], bool)


def detector_settings() -> dict:
    """The annotation settings the ``detector`` calibration counts with (``AnnotateParams`` defaults:
    the paper's Eq. 1-2 and the pipeline's window trimming); part of the corpus parameter hash."""
    from ..annotate.params import AnnotateParams

    ap = AnnotateParams()
    return {"alpha_s": float(ap.alpha_s), "alpha_w": float(ap.alpha_w), "extend_trim": bool(ap.extend_trim),
            "up_axis": int(ap.up_axis)}


def _segment_frame(segs: list[Segment]) -> tuple[pd.DataFrame, list[Segment]]:
    """DataFrame[kind, start, end] of one participant's segments, in time order, and those segments."""
    segs = sorted(segs, key=lambda sg: sg.start)
    return pd.DataFrame({"kind": [sg.kind for sg in segs], "start": [sg.start for sg in segs],
                         "end": [sg.end for sg in segs]}), segs


def _detector_matches(plan: dict, cfg: dict) -> dict:
    """{(role, hypothesis): (matched, caused)} of one planned session as the annotation pipeline counts
    it (``calibrate_against="detector"``): each participant's motion is rendered exactly as it will be
    written, its joint speeds and Eq. 1 recording thresholds computed, and every hypothesis counted by
    ``stats.cooccurrence.hypothesis_matches`` over the planted audio segments (Table 1 counts over the
    detected ones; the two differ where clause segmentation does)."""
    from ..annotate.motion import joint_speeds, recording_thresholds
    from ..annotate.params import AnnotateParams
    from ..stats.cooccurrence import hypothesis_matches

    st = detector_settings()
    ap = AnnotateParams(alpha_s=st["alpha_s"], alpha_w=st["alpha_w"], extend_trim=st["extend_trim"],
                        up_axis=st["up_axis"])
    frames = {r: _segment_frame([sg for sg in plan["segs"] if sg.role == r]) for r in ROLES}
    out = {}
    for k, role in enumerate(ROLES):
        motion, _ = _render_motion(plan, role, cfg)
        speeds = joint_speeds(motion, ap)
        thr = recording_thresholds(speeds, ap.alpha_s)
        (own, own_segs), (partner, partner_segs) = frames[role], frames[ROLES[1 - k]]
        for h, (akind, _, whose, _) in HYPOTHESIS_KEYS.items():
            hit, _ = hypothesis_matches(speeds, own, partner, motion.fps, h, thresholds=thr, alpha_w=ap.alpha_w,
                                        extend_trim=ap.extend_trim)
            audio = [sg for sg in (own_segs if whose == "own" else partner_segs) if sg.kind == akind]
            out[(role, h)] = (hit, _caused(plan, role, h, audio))
    return out


def _window_matches_all(plan: dict, cfg: dict) -> dict:
    return {(r, h): _plan_matches(plan, r, h) for r in ROLES for h in HYPOTHESIS_KEYS}


# how the calibration measures a planned session's realized rates (generator key calibrate_against)
CALIBRATION_MEASURES = {"detector": _detector_matches, "windows": _window_matches_all}


def planting_probabilities(cfg: dict) -> tuple[dict, dict]:
    """Per role the probabilities to plant with, and a report. Without ``calibrate_rates`` the
    configured ones. With it: movements that belong to other segments (a gesture of the next clause,
    a nod for a listener response) or spontaneous ones also land in windows of segments that caused
    nothing, at a rate q, and a share m of the causing segments' windows miss their movement (the
    previous window's movement runs into them, or it was dropped for coming too close to another),
    so the realized window rate is about p' (1 - m) + (1 - p') q. The realized rates are measured on
    this very corpus (same seed and conversations) by ``calibrate_against``: ``detector`` renders the
    motion and counts with the annotation pipeline's detector and counter (``_detector_matches``),
    ``windows`` counts the planned movement intervals (``window_matches``, no rendering). p' is moved
    by the remaining error, p' <- p' + (p - realized(p')) (planting is nested in p', see
    ``_plant_events``, so nearby p' give nearby corpora and the full step converges in a few passes),
    for ``calibration_passes`` passes or until every realized rate is within
    ``calibration_tolerance`` of the configured one. Since the corpus is a deterministic
    function of p', the pass with the smallest largest error is the corpus that gets written; the
    report gives each pass's p', realized rates, q and m, and the chosen pass."""
    conf = {r: {HYPOTHESIS_KEYS[h][3]: float(cfg["characters"][r][HYPOTHESIS_KEYS[h][3]]) for h in HYPOTHESIS_KEYS}
            for r in ROLES}
    if not cfg["calibrate_rates"]:
        return conf, {}
    measure = CALIBRATION_MEASURES[cfg["calibrate_against"]]
    probs, report = copy.deepcopy(conf), {"measure": cfg["calibrate_against"], "passes": []}
    if cfg["calibrate_against"] == "detector":
        report["detector"] = detector_settings()
    offsets = _quota_offsets(cfg)
    best = (np.inf, conf)
    for _ in range(int(cfg["calibration_passes"])):
        flags = [measure(_plan(i, cfg, probs, offsets), cfg) for i in range(int(cfg["num_sessions"]))]
        new, rows, worst = copy.deepcopy(conf), {}, 0.0
        for r in ROLES:
            for h, (_, _, _, key) in HYPOTHESIS_KEYS.items():
                m = np.concatenate([f[(r, h)][0] for f in flags])
                c = np.concatenate([f[(r, h)][1] for f in flags])
                q = float(m[~c].mean()) if (~c).any() else 0.0
                miss = float(1.0 - m[c].mean()) if c.any() else 0.0
                realized = float(m.mean()) if m.size else conf[r][key]
                worst = max(worst, abs(realized - conf[r][key]))
                # fixed-point step: shift p' by the remaining error of the realized rate
                new[r][key] = float(np.clip(probs[r][key] + conf[r][key] - realized, 0.0, 1.0))
                rows[f"{r} {h}"] = {"planted_with": round(probs[r][key], 4), "realized": round(realized, 4),
                                    "q": round(q, 4), "miss": round(miss, 4)}
            pr = new[r]  # keep the PC probabilities consistent: max(lh, rh) <= either <= lh + rh
            pr["p_pc_either"] = float(np.clip(pr["p_pc_either"], max(pr["p_pc_lh"], pr["p_pc_rh"]),
                                              min(1.0, pr["p_pc_lh"] + pr["p_pc_rh"])))
        report["passes"].append({"max_abs_error": round(worst, 4), "rows": rows})
        if worst < best[0]:  # a plan is a deterministic function of p': the best pass is the corpus
            best = (worst, probs)
        if worst <= float(cfg["calibration_tolerance"]):
            break
        probs = new
    report["chosen_pass"] = int(np.argmin([ps["max_abs_error"] for ps in report["passes"]]))
    probs = best[1]
    return probs, report


def _session(idx: int, cfg: dict, probs: dict, offsets: list[dict], out: Path) -> tuple[list[dict], list[dict], dict]:
    plan = _plan(idx, cfg, probs, offsets)
    name, duration, segs = plan["name"], plan["duration"], plan["segs"]
    sr = int(cfg["sample_rate"])
    rows, glitch_rows = [], []
    for role in ROLES:
        ch = cfg["characters"][role]
        own = [s for s in segs if s.role == role]
        events = plan["events"][role]
        motion, gl = _render_motion(plan, role, cfg)
        glitch_rows += [{"session": name, "participant": role, **g} for g in gl]
        save_bvh(motion, out / f"{name}_{role}.bvh", precision=4)
        words = [(w[0], w[1], w[2]) for s in own for w in s.words]
        save_transcript_tsv(pd.DataFrame(words, columns=["start", "end", "word"]), out / f"{name}_{role}.tsv")
        if cfg["write_audio"]:
            sig, _ = _render_voice(own, ch["f0"], duration, sr, _render_rng(cfg, idx, role, "audio"),
                                   cfg["accent_rise"])
            save_wav(out / f"{name}_{role}.wav", sig, sr)
        for s in own:
            rows.append({"session": name, "participant": role, "kind": s.kind, "start": s.start, "peak": s.peak,
                         "end": s.end, "text": " ".join(w[2] for w in s.words), "source": "", "cause_start": np.nan})
        for e in events:
            rows.append({"session": name, "participant": role, "kind": e["kind"], "start": e["start"],
                         "peak": e["peak"], "end": e["end"], "text": "", "source": e["source"],
                         "cause_start": e.get("cause_start", np.nan)})
    return rows, glitch_rows, {"name": name, "emotion": plan["emotion"], "duration": duration,
                               "spontaneous_free_seconds": {r: round(v, 4) for r, v in plan["free_seconds"].items()}}


GLITCH_COLUMNS = ["session", "participant", "kind", "joint", "channel", "degrees", "start_frame", "end_frame"]


def _shift_times(segs: list[Segment], role: str, events: list[dict], duration: float, longest: float) -> list[float]:
    """When ``role`` shifts its posture: once before each of its turns, in the last stretch before
    the turn that is free of its candidate windows (own segments, partner's hesitations) and of its
    movements, so a posture shift never lands in a window (like spontaneous movements); a turn
    without such a stretch since the previous shift gets none."""
    partner = ROLES[1 - ROLES.index(role)]
    busy = [_window(sg) for sg in segs if sg.role == role or (sg.role == partner and sg.kind == "HP")]
    busy += [(e["start"] - 0.2, e["end"] + 0.2) for e in events]
    free = _free_intervals(busy, 1.0, duration - 1.5)
    need = longest + 0.2
    out, last = [], -np.inf
    for tau in _turn_starts(segs, role):
        fits = [(a, b) for a, b in free if b <= tau + 1e-9 and b - max(a, last) >= need]
        if fits:
            a, b = fits[-1]
            out.append(b - need + 0.1)
            last = b
    return out


def _turn_starts(segs: list[Segment], role: str) -> list[float]:
    """Start times of ``role``'s turns: its clauses that follow a clause of the other participant."""
    out, last = [], None
    for s in segs:  # sorted by start
        if s.kind != "PC":
            continue
        if s.role == role and last is not None and last != role:
            out.append(s.start)
        last = s.role
    return out


def make_synthetic_corpus(out_dir: str | Path, config=None) -> Path:
    """Write the synthetic corpus into ``out_dir`` (replaced atomically). Same seed, same bytes."""
    cfg = resolve_config(config)
    out_dir = Path(out_dir)
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.", dir=out_dir.parent))
    try:
        probs, calibration = planting_probabilities(cfg)
        offsets = _quota_offsets(cfg)
        rows, glitches, sessions = [], [], []
        for i in range(int(cfg["num_sessions"])):
            r, g, meta = _session(i, cfg, probs, offsets, tmp)
            rows += r
            glitches += g
            sessions.append(meta)
        ev = pd.DataFrame(rows).round({"start": 4, "peak": 4, "end": 4, "cause_start": 4})
        ev.to_csv(tmp / "events.csv", index=False, float_format="%.4f")
        gl = pd.DataFrame(glitches, columns=GLITCH_COLUMNS)
        gl.to_csv(tmp / "glitches.csv", index=False, float_format="%.4f")
        meta = {"generator": "convsynth_jax.data.synthetic", "generator_version": GENERATOR_VERSION,
                "seed": int(cfg["seed"]), "config": cfg, "config_hash": config_hash(cfg),
                "characters": {r: cfg["characters"][r]["name"] for r in ROLES}, "sessions": sessions,
                "calibration": calibration}
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
