"""Hand-model datasets for the Sec. VIII evaluation (Table V analogue): turns whose motion is the 10-D
arm/forearm stream of cdbn/hands.py.

* :func:`dyadic_hand_turns`: the framework's synthetic dyadic corpus; speech = each clip's own audio
  channel, constraints = the own-channel audio labels (idle / PC / LR / HP), each clip cut into turns
  of ``turn_seconds`` for the cross-validation; subject = character.
* :func:`bandai_hand_turns`: real motion capture (Bandai-Namco-Research-Motiondataset-2, raise and wave
  clips). It has no audio: each clip is paired with an excerpt of a real recording (ours), so the
  speech-motion coupling is absent by construction and only the motion side (does the constraint
  produce the gesture) is meaningful. Constraints: one per prototypical gesture, as in the paper
  (Sec. IV-D: each constraint is one gesture, e.g. So-What), so left, right and both-hands raises
  and waves are six constraints (``gestures="per_side"``; ``"pooled"``, ours: raise / wave); the
  constraint spans the gesture, from the first to the last frame whose arms are away from rest
  (:func:`gesture_span`; ``span="fraction"``, ours: everything but the clip's first and last
  ``rest_fraction``); the clip's remaining frames are ``other``. Why (measured on Bandai2,
  ``cdbn_raise.py``, a diagnosis since retired, in git at e1848f1): a pooled ``raise`` does not say which arm to lift, so the
  synthesized raise is an average of the three, and a 15% margin holds most of a 2 s raise's lift.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import CDBNError
from .dataset import Turn
from .features import speech_features
from .hands import arm_angles, arm_rig
from .params import CDBNFeatureParams

DYADIC_CONSTRAINTS = ("idle", "PC", "LR", "HP")
BANDAI_GESTURES = ("raise-up-left-hand", "raise-up-right-hand", "raise-up-both-hands",
                   "wave-left-hand", "wave-right-hand", "wave-both-hands")
BANDAI_CONSTRAINTS = ("other", *BANDAI_GESTURES)
BANDAI_POOLED_CONSTRAINTS = ("other", "raise", "wave")


def bandai_constraints(gestures: str = "per_side") -> tuple:
    """Constraint names of :func:`bandai_hand_turns`: ``per_side`` (other + six gestures) or
    ``pooled`` (other, raise, wave)."""
    if gestures not in ("per_side", "pooled"):
        raise CDBNError(f"gestures must be 'per_side' or 'pooled', got {gestures!r}")
    return BANDAI_CONSTRAINTS if gestures == "per_side" else BANDAI_POOLED_CONSTRAINTS


def gesture_kind(name: str) -> str:
    """'raise' or 'wave' of a Bandai2 gesture or clip name (the side left out)."""
    return "raise" if "raise" in name else "wave" if "wave" in name else name


def gesture_span(angles: np.ndarray, rest_threshold: float = 0.1) -> tuple[int, int]:
    """(first, stop) frames of the gesture in a clip that starts and ends at rest. angles: (T, 10)
    arm/forearm angles (degrees). A frame is away from rest when its distance to the nearer of the
    first and last poses exceeds ``rest_threshold`` times the clip's largest such distance; the span
    runs from the first to the last such frame (whole clip when the arms never move)."""
    a = np.asarray(angles, np.float64)
    away = np.minimum(np.linalg.norm(a - a[0], axis=1), np.linalg.norm(a - a[-1], axis=1))
    on = np.flatnonzero(away > rest_threshold * away.max()) if away.max() > 0 else np.array([], int)
    return (int(on[0]), int(on[-1]) + 1) if len(on) else (0, len(a))


def dyadic_hand_turns(corpus, ann, fp: CDBNFeatureParams, turn_seconds: float = 10.0, max_sessions: int | None = None):
    """(turns, rig) from an annotated corpus (session -> role -> annotation)."""
    from ..io.audio import load_audio

    paths = {(s.name, p.role): (p.audio_path, p.audio_channel) for s in corpus.sessions for p in s.participants}
    turns, rig = [], None
    for sname in sorted(ann)[:max_sessions]:
        for role, clip in sorted(ann[sname].items()):
            rig = rig or arm_rig(clip.motion.skeleton, fp)
            m = arm_angles(clip.motion, fp, rig)
            path, ch = paths[(sname, role)]
            s = speech_features(load_audio(path, channel=ch), fp, len(m), clip.motion.fps, path=path)
            lab = np.asarray(clip.own.label, np.int32)[: len(m)]
            step = int(round(turn_seconds * clip.motion.fps))
            for k, a in enumerate(range(0, len(m) - step // 2, step)):
                b = min(a + step, len(m))
                turns.append(Turn(f"{sname}_{role}_{k:03d}", str(clip.character), s[a:b], m[a:b], lab[a:b]))
    return turns, rig


def bandai_hand_turns(bvh_dir, wav, fp: CDBNFeatureParams, rest_fraction: float = 0.15, max_clips: int | None = None,
                      seed: int = 0, gestures: str = "per_side", span: str = "motion", rest_threshold: float = 0.1):
    """(turns, rig) from the raise/wave clips of a Bandai2 ``bvh`` folder, each paired with a random
    stretch of the prosody track of ``wav`` (analysed once, whole) of the clip's length; subject = the
    clip's style (all 'normal' here). Constraint codes index ``bandai_constraints(gestures)``; the
    gesture spans :func:`gesture_span` (``span="motion"``) or all but ``rest_fraction`` at each end
    (``span="fraction"``)."""
    names = bandai_constraints(gestures)
    if span not in ("motion", "fraction"):
        raise CDBNError(f"span must be 'motion' or 'fraction', got {span!r}")
    from ..io.audio import load_audio
    from ..io.bvh import load_bvh

    rng = np.random.default_rng(seed)
    audio = load_audio(wav)
    track = speech_features(audio, fp, int(round(audio.duration * fp.fps)), fp.fps, path=wav)
    files = sorted(f for f in Path(bvh_dir).glob("*.bvh") if "raise" in f.name or "wave" in f.name)
    if max_clips:
        files = [files[i] for i in np.sort(rng.choice(len(files), min(max_clips, len(files)), replace=False))]
    turns, rig = [], None
    for f in files:
        mo = load_bvh(f)
        if abs(mo.fps - fp.fps) > 1e-6:
            mo = mo.resample(fp.fps)
        rig = rig or arm_rig(mo.skeleton, fp)
        m = arm_angles(mo, fp, rig)
        n = len(m)
        if n > len(track):
            raise CDBNError(f"clip {f.name} ({n} frames) is longer than the speech ({len(track)} frames)", wav)
        a0 = int(rng.integers(0, len(track) - n + 1))
        s = track[a0:a0 + n]
        gesture = next((g for g in BANDAI_GESTURES if f"_{g}_" in f.name), None)
        if gesture is None:
            raise CDBNError(f"clip {f.name}: not one of the gestures {BANDAI_GESTURES}", f)
        c = np.zeros(n, np.int32)
        if span == "motion":
            a, b = gesture_span(m, rest_threshold)
        else:
            r = int(round(rest_fraction * n))
            a, b = r, n - r
        c[a:b] = names.index(gesture if gestures == "per_side" else gesture_kind(gesture))
        turns.append(Turn(f.stem, f.stem.split("_")[-2], s, m, c))
    return turns, rig


def present_constraints(turns, names: tuple):
    """(turns, names) keeping only the constraints that occur in ``turns`` (the first, ``other``,
    always), codes renumbered: a clip selection without, e.g., left-hand waves trains no model for
    them."""
    used = np.zeros(len(names), bool)
    used[0] = True
    for t in turns:
        used[np.unique(t.constraints)] = True
    code = np.cumsum(used) - 1
    return [t._replace(constraints=code[t.constraints].astype(np.int32)) for t in turns], \
        tuple(n for n, u in zip(names, used) if u)


def hand_evaluation(turns, rig, names: tuple, eval_kw: dict, base=None) -> dict:
    """The Sec. VIII protocol (run_cdbn_evaluation) on hand turns: Table V analogue (states, parameters,
    CCA_m, CCA_ms, KLD per model), gesture accuracy of the synthesized segments (``original``: the
    classifier on the original motion of the same segments), also by kind (raise / wave, side left
    out), validation curves."""
    import dataclasses
    import time

    from .dataset import normalize_by_subject
    from .experiment import CDBNEvalParams, run_cdbn_evaluation
    from .params import CDBNParams

    turns, names = present_constraints(turns, names)
    p = dataclasses.replace(base or CDBNParams(), constraints=tuple(names))
    zt, norms = normalize_by_subject(turns)
    t0 = time.perf_counter()
    res = run_cdbn_evaluation(zt, norms, p, CDBNEvalParams(**eval_kw), rig=rig)
    counts = np.bincount(np.concatenate([t.constraints for t in turns]), minlength=len(names))
    return {"turns": len(turns), "frames": int(sum(len(t.speech) for t in turns)),
            "frames_per_constraint": dict(zip(names, counts.tolist())), "eval": dict(eval_kw),
            "chosen_states": res["chosen_states"], "validation_curves": res["validation_curves"],
            "table": res["table"], "gesture_accuracy": res["gesture_accuracy"],
            "gesture_accuracy_by_kind": accuracy_by_kind(res["gesture_predictions"]),
            "gesture_confusion": res["gesture_confusion"], "gesture_predictions": res["gesture_predictions"],
            "tests": res["tests"],
            "cca_original_speech_motion": res["cca_original_speech_motion"], "test_folds": res["test_folds"],
            "seconds": time.perf_counter() - t0}


def accuracy_by_kind(predictions: dict) -> dict:
    """{model: {kind: {n, accuracy}}}: share of each kind's segments (raise / wave) predicted as a
    gesture of that kind, whatever its side. predictions: {model: [{truth, predicted}, ...]}."""
    out = {}
    for model, rows in predictions.items():
        out[model] = {}
        for kind in sorted({gesture_kind(r["truth"]) for r in rows}):
            mine = [r for r in rows if gesture_kind(r["truth"]) == kind]
            out[model][kind] = {"n": len(mine), "accuracy": float(np.mean([gesture_kind(r["predicted"]) == kind
                                                                           for r in mine]))}
    return out
