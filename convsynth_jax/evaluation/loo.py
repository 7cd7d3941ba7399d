"""Leave-one-out evaluation (paper Section 8) for any synthesis system.

Hold out one session, fit the system on the other sessions (one model per character, shared by
every condition with the same ``fit_key``), slide windows (15 s, 14 s hop) over the held-out audio
and synthesize both characters in each window under one ablation condition, a key of the system's
``conditions`` (``conf/system/<name>.yaml``). Each (window, character) becomes one row of generic
fields: success, timings, constraints met, the independent checker's verdict where the system
reports per-frame provenance, co-occurrence counts of ground truth and synthesized motion, and
motion-quality metrics; system-specific scalars come as ``diag_<key>`` columns.

Co-occurrence is counted by Table 1's function (``stats.cooccurrence.hypothesis_matches``) with
Eq. 1's idle thresholds of a recording, never of the window: the ground truth of a held-out window
uses its recording's own thresholds, synthesized motion the mean thresholds of the character's
training recordings (``fold_thresholds``; our choice, the paper is silent). Every system is scored
this way; one without hand motion (``produces_hands`` False) gets NaN hand hypotheses.

There is one loop: :func:`loo_cases` yields, per fold, condition, window and character, the input the
system saw, its result (motion, timing, constraints, per-frame provenance) and the recording's ground
truth; :func:`run_fold` (and through it the tasks and the benchmark) reduces it to rows with
:func:`score_case`, and an analysis reduces it its own way instead of rewriting the loop. It passes the
system's options and conditions as they are and never changes them.

Nothing here knows a particular system: what only a system can tell (the motion graph's independent
constraint checker, the joint positions of the training clips it played back) comes through the
interface's ``window_diagnostics`` and ``source_positions`` hooks.
"""
from __future__ import annotations

import functools
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator, Optional, Sequence, Union

import numpy as np
import pandas as pd

from ..annotate.kinds import hypotheses
from ..errors import ConfigError
from ..seeding import derive_seed
from ..systems.base import SynthesisSystem, WindowInput, WindowResult
from .windows import Window, sliding_windows, window_segments

log = logging.getLogger(__name__)

HAND_HYPOTHESES = tuple(h.name for h in hypotheses() if {"LH", "RH"} & set(h.motions))   # the registry's


def training_clips(annotations: dict, held_out: str, character: str) -> list:
    """The ParticipantAnnotation records of ``character`` in every session but ``held_out``."""
    return [a for s, d in annotations.items() if s != held_out for a in d.values() if a.character == character]


def characters(annotations: dict) -> list[str]:
    return sorted({a.character for d in annotations.values() for a in d.values()})


def fit_fold(system: SynthesisSystem, annotations: dict, held_out: str, condition: str, cache_dir=None,
             models: dict | None = None) -> dict:
    """character -> fitted model for ``condition``; ``models`` (a dict kept across conditions of one
    fold) memoizes fits by (character, system.fit_key(condition))."""
    models = {} if models is None else models
    out = {}
    for char in characters(annotations):
        key = (char, system.fit_key(condition))
        if key not in models:
            clips = training_clips(annotations, held_out, char)
            if not clips:
                raise ConfigError(f"no training recordings of {char!r} outside the held-out session {held_out!r}: "
                                  "leave-one-out needs at least two sessions")
            models[key] = system.fit(clips, char, condition, cache_dir)
        out[char] = models[key]
    system.prepare(out)
    return out


def recording_threshold_table(annotations: dict, annotate) -> dict:
    """(session, role) -> Eq. 1's θ_S per motion kind over that participant's whole clip. A sweep
    computes it once and passes it to every fold (``run_fold(thresholds=...)``): forward kinematics
    over every recording is the costly part."""
    from ..annotate.motion import joint_speeds, recording_thresholds

    return {(s, r): recording_thresholds(joint_speeds(a.motion, annotate), annotate.alpha_s)
            for s, d in annotations.items() for r, a in d.items()}


def fold_thresholds(annotations: dict, held_out: str, annotate, table: dict | None = None) -> tuple[dict, dict]:
    """(role -> θ_S of each held-out recording over its own whole clip, character -> mean θ_S of
    the character's training recordings) for the fold holding out ``held_out``. ``table``: a
    ``recording_threshold_table`` to reuse across folds (computed here when None)."""
    from ..annotate.motion import character_thresholds

    if held_out not in annotations:
        raise ConfigError(f"no session {held_out!r}; sessions are {list(annotations)}")
    table = recording_threshold_table(annotations, annotate) if table is None else table
    gt = {r: table[(held_out, r)] for r in annotations[held_out]}
    synth = {}
    for char in characters(annotations):
        train = [table[(s, r)] for s, d in annotations.items() if s != held_out for r, a in d.items()
                 if a.character == char]
        if not train:
            raise ConfigError(f"no training recordings of {char!r} outside the held-out session {held_out!r}: "
                              "leave-one-out needs at least two sessions")
        synth[char] = character_thresholds(train)
    return gt, synth


def session_windows(held: dict, fps: float, length: float, hop: float, max_windows: int | None = None) -> list[Window]:
    duration = min(a.motion.num_frames for a in held.values()) / fps
    windows = sliding_windows(duration, length, hop)
    return windows[: int(max_windows)] if max_windows else windows


@functools.lru_cache(maxsize=4)
def _recording_audio(path: str, channel, content: str = ""):
    """One participant's whole recording, read once for all of its windows (the two roles of the
    held-out session are the ones in use at a time); ``content``: the file's digest, so a file edited
    in place is read again."""
    from ..io import load_audio

    return load_audio(path, channel=channel)


def _audio_slice(ann, w: Window):
    """The window's samples of a participant's audio (None without audio)."""
    if not getattr(ann, "audio_path", None):
        return None
    from ..io.audio import Audio

    from ..fingerprint import file_digest

    aud = _recording_audio(str(ann.audio_path), ann.audio_channel, file_digest(ann.audio_path))
    a0, a1 = int(round(w.start * aud.sample_rate)), int(round(w.end * aud.sample_rate))
    return Audio(aud.samples[a0:a1], aud.sample_rate)


def window_input(held: dict, role: str, w: Window, fps: float, seed: int, with_audio: bool = False,
                 own_segments: pd.DataFrame | None = None, partner_segments: pd.DataFrame | None = None) -> WindowInput:
    """The WindowInput of ``role`` in window ``w`` of a held-out session (``held``: role ->
    ParticipantAnnotation). Segments default to the session's annotation (``task=synthesize``
    passes those of new audio)."""
    roles = list(held)
    k = roles.index(role)
    ann, partner = held[role], held[roles[1 - k]]
    f0, n = int(round(w.start * fps)), int(round(w.duration * fps))
    own_seg = window_segments(ann.segments if own_segments is None else own_segments, w)
    par_seg = window_segments(ann.partner_segments if partner_segments is None else partner_segments, w)
    return WindowInput(
        session=ann.session, role=role, character=ann.character, start_frame=f0, num_frames=n, fps=fps,
        own_segments=own_seg, partner_segments=par_seg,
        own_frames=ann.own.slice(f0, f0 + n), partner_frames=ann.partner.slice(f0, f0 + n),
        own_audio=_audio_slice(ann, w) if with_audio else None,
        partner_audio=_audio_slice(partner, w) if with_audio else None,
        chair_index=k, seed=seed)


def window_cooccurrence(motion, own_segments, partner_segments, thresholds: dict, params, prefix: str,
                        hands: bool = True) -> dict:
    """``<prefix>_<hypothesis>_matched`` / ``_total`` for one window of motion, counted by Table 1's
    ``hypothesis_matches`` with the given recording thresholds (Eq. 1); hand hypotheses are NaN
    ("not applicable") for motion without hand gestures."""
    from ..annotate.motion import joint_speeds
    from ..stats.cooccurrence import window_counts

    ap = params.annotate
    counts = window_counts(joint_speeds(motion, ap), own_segments, partner_segments, motion.fps, thresholds, ap)
    out = {}
    for h, (matched, total) in counts.items():
        na = not hands and h in HAND_HYPOTHESES
        out[f"{prefix}_{h}_matched"] = np.nan if na else matched
        out[f"{prefix}_{h}_total"] = np.nan if na else total
    return out


def source_window_cooccurrence(source_clips, source_frames, speeds: dict, own_segments, partner_segments, fps: float,
                               thresholds: dict, params, prefix: str) -> dict:
    """:func:`window_cooccurrence`'s counts read from the source recordings (ours): each output frame's
    hand and head speed is the speed its source frame has in its recording (``speeds``: clip name ->
    ``annotate.motion.joint_speeds`` of that recording), so a movement counts only where a recording
    made it; a blend or a cut, which moves the hands between two unrelated poses, is never read as a
    gesture. For a window of one recording played as it is (the ground truth: its own recording as
    source) the speeds, and so the counts, are the recording's (up to the window's edge frames, where
    ``joint_speeds`` of the cut window differ)."""
    from ..stats.cooccurrence import window_counts

    frames = np.asarray(source_frames, np.int64)
    sp = {k: np.array([speeds[c][k][f] for c, f in zip(source_clips, frames)], np.float64)
          for k in ("LH", "RH", "Nod")}
    counts = window_counts(sp, own_segments, partner_segments, fps, thresholds, params.annotate)
    out = {}
    for h, (matched, total) in counts.items():
        out[f"{prefix}_{h}_matched"] = matched
        out[f"{prefix}_{h}_total"] = total
    return out


def _metric_points(motion, head_only: bool, params) -> np.ndarray:
    """(F, P, 3) float64 points the quality metrics are computed on: every joint (forward
    kinematics), or the head point only (``annotate.motion.head_point``)."""
    if head_only:
        from ..annotate.motion import head_point

        return head_point(motion, params.annotate)[:, None, :]
    from ..kinematics import forward_kinematics

    return np.asarray(forward_kinematics(motion), dtype=np.float64)


@dataclass(frozen=True)
class WindowCase:
    """One synthesized (window, character) of a leave-one-out fold: what went in, what came out and
    what was recorded (:func:`loo_cases`).

    system: its name; fold / held_out: the fold index and the held-out session; condition: the
    ablation condition; window: the :class:`~.windows.Window`; role / character: who was synthesized;
    input: the :class:`WindowInput` the system saw; model: the fitted model that synthesized it;
    result: the :class:`WindowResult` (motion, timing, constraints, per-frame provenance:
    ``source_clip`` / ``source_frame`` / ``synthetic_at``), None when ``synthesize`` raised (``error``
    says what); ground_truth: the held-out recording's Motion over the window.
    """

    system: str
    fold: int
    held_out: str
    condition: str
    window: Window
    role: str
    character: str
    input: WindowInput
    model: Any
    result: Optional[WindowResult]
    ground_truth: Any
    error: Optional[str] = None


def loo_cases(system: SynthesisSystem, annotations: dict, params, folds: Union[int, Sequence[int]],
              conditions: Union[str, Sequence[str]], *, cache_dir: str | Path | None = None,
              models: dict | None = None, with_audio: bool = False,
              max_windows: int | None = None) -> Iterator[WindowCase]:
    """The one leave-one-out loop: for each fold, each condition, each window of the held-out session
    (15 s, 14 s hop: ``params.loo``) and each of its two characters, a :class:`WindowCase`. Models are
    fitted once per fold and ``fit_key`` (``fit_fold``; ``models``: a dict kept across calls, cleared
    between folds when the loop made it); seeds come from :func:`convsynth_jax.seeding.derive_seed`.
    :func:`run_fold`, the tasks, the benchmark and the analyses reduce over it.

    Nothing is mutated: the system's options and conditions are those it was made with (to compare
    options, make one system per option set with ``make_system``); a synthesis that raises is yielded
    with its ``error``, never ends the loop. Unknown conditions and folds out of range fail before
    any work. ``max_windows``: overrides ``params.loo.max_windows``."""
    folds = [int(folds)] if isinstance(folds, (int, np.integer)) else [int(f) for f in folds]
    conditions = [conditions] if isinstance(conditions, str) else list(conditions)
    for condition in conditions:
        system.condition_options(condition)  # unknown conditions fail before any work
    names = list(annotations)
    if len(names) < 2:
        raise ConfigError(f"leave-one-out needs at least two sessions; the corpus has {len(names)}")
    for fold in folds:
        if not 0 <= fold < len(names):
            raise ConfigError(f"fold {fold} out of range: the corpus has {len(names)} sessions")
    fps = float(params.features.fps)
    limit = params.loo.max_windows if max_windows is None else max_windows
    for fold in folds:
        held_out = names[fold]
        held = annotations[held_out]
        fold_models = {} if models is None else models
        for condition in conditions:
            fitted = fit_fold(system, annotations, held_out, condition, cache_dir, fold_models)
            for w in session_windows(held, fps, params.loo.window, params.loo.hop, limit):
                for k, (role, ann) in enumerate(held.items()):
                    f0 = int(round(w.start * fps))
                    seed = derive_seed(params.seed, fold=fold, condition=condition, session=held_out,
                                       window_frame=f0, role_index=k)
                    win = window_input(held, role, w, fps, seed, with_audio=with_audio)
                    gt = ann.motion.slice(f0, f0 + win.num_frames)
                    model = fitted[ann.character]
                    try:
                        res, error = system.synthesize(model, win, condition), None
                    except Exception as e:  # recorded, never ends the sweep
                        log.exception("%s window at frame %d, %s failed", win.session, win.start_frame, win.character)
                        res, error = None, f"{type(e).__name__}: {e}"
                    yield WindowCase(system.name, fold, held_out, condition, w, role, ann.character, win, model,
                                     res, gt, error)


def score_case(system: SynthesisSystem, case: WindowCase, params, *, gt_thresholds: dict,
               synth_thresholds: dict) -> dict:
    """One row of a synthesized window: generic fields, the system's ``window_diagnostics``, metrics.

    gt_thresholds: Eq. 1's θ_S per kind of the held-out recording (its whole clip); synth_thresholds:
    those for the character's synthesized motion (``fold_thresholds``)."""
    from . import metrics

    win, model, gt_motion, res = case.input, case.model, case.ground_truth, case.result
    fps = win.fps
    row = {"fit_seconds": system.fit_seconds(model), "status": "ok"}
    if res is None:
        return {**row, "success": False, "status": "error", "error": case.error}
    row.update({"success": bool(res.success), "synthesis_seconds": res.seconds, "failure": res.failure,
                "constraints_total": res.constraints_total, "constraints_met": res.constraints_met})
    row.update({f"diag_{k}": v for k, v in res.diagnostics.items() if np.isscalar(v)})
    own, partner = win.own_segments, win.partner_segments
    if res.success:
        row.update(system.window_diagnostics(model, win, res))
    # Motion-quality metrics over every joint, or for a head-only system (no hands) over the head
    # point alone, in both the ground truth and the synthesis: a still body would otherwise score
    # zero jerk and hide what the system does (metric_scope says which).
    head_only = not system.produces_hands
    gt_pos = _metric_points(gt_motion, head_only, params)
    row["metric_scope"] = "head" if head_only else "body"
    row.update(window_cooccurrence(gt_motion, own, partner, gt_thresholds, params, "gt"))
    row.update({"gt_jerk": metrics.mean_jerk(gt_pos, fps), "gt_acceleration": metrics.mean_acceleration(gt_pos, fps),
                "gt_max_jump": float(metrics.max_frame_jump(gt_pos).max(initial=0.0))})
    if res.success and res.motion is not None:
        pos = _metric_points(res.motion, head_only, params)
        row.update(window_cooccurrence(res.motion, own, partner, synth_thresholds, params, "synth",
                                       hands=system.produces_hands))
        row.update({
            "jerk": metrics.mean_jerk(pos, fps), "acceleration": metrics.mean_acceleration(pos, fps),
            "speed_hellinger": metrics.speed_histogram_distance(pos, gt_pos, fps),
            "max_jump": float(metrics.max_frame_jump(pos).max(initial=0.0)),
            "num_synthetic_transitions": len(res.synthetic_at) if res.synthetic_at is not None else np.nan,
            "seam_ratio": metrics.seam_ratio(pos, gt_pos, fps, [] if res.synthetic_at is None else list(res.synthetic_at)),
        })
        if not head_only and res.source_clip is not None and res.synthetic_at:
            # played-back output: what the source clips' own content brings to the seams
            src = {c: system.source_positions(model, c) for c in set(res.source_clip)}
            if all(p is not None for p in src.values()):
                acc = {c: metrics.clip_acceleration(p, fps) for c, p in src.items()}
                row["seam_content_ratio"] = metrics.seam_content_ratio(
                    acc, list(res.source_clip), [int(f) for f in res.source_frame], gt_pos, fps,
                    list(res.synthetic_at), int(res.blend_frames))
    return row


def evaluate_window(system: SynthesisSystem, model, win: WindowInput, condition: str, gt_motion, params, *,
                    gt_thresholds: dict, synth_thresholds: dict) -> tuple[dict, object]:
    """One window synthesized and scored outside :func:`loo_cases` (e.g. a test's own window): (the row
    of :func:`score_case`, the synthesized Motion or None)."""
    try:
        res, error = system.synthesize(model, win, condition), None
    except Exception as e:  # recorded as the loop records it
        log.exception("%s window at frame %d, %s failed", win.session, win.start_frame, win.character)
        res, error = None, f"{type(e).__name__}: {e}"
    w = Window(-1, win.start_frame / win.fps, (win.start_frame + win.num_frames) / win.fps)
    case = WindowCase(system.name, -1, win.session, condition, w, win.role, win.character, win, model, res,
                      gt_motion, error)
    row = score_case(system, case, params, gt_thresholds=gt_thresholds, synth_thresholds=synth_thresholds)
    return row, (res.motion if res is not None and res.success else None)


def run_fold(system: SynthesisSystem, annotations: dict, fold: int, condition: str, params, out_dir: Path | None = None,
             cache_dir: str | Path | None = None, export_bvh: bool = False, models: dict | None = None,
             with_audio: bool = False, thresholds: dict | None = None) -> pd.DataFrame:
    """All test cases of one fold in one condition: one row per (window, character), a reduction of
    :func:`loo_cases`.

    models: fitted models kept across the conditions of one fold (``fit_fold``); thresholds: a
    ``recording_threshold_table`` of ``annotations`` kept across folds (computed here when None)."""
    from ..io import save_bvh
    from ..kinematics import pose_features
    from . import metrics

    cases = loo_cases(system, annotations, params, fold, condition, cache_dir=cache_dir, models=models,
                      with_audio=with_audio)
    rows, synth_windows, thresholds_of = [], {}, None
    for case in cases:
        if thresholds_of is None:
            thresholds_of = fold_thresholds(annotations, case.held_out, params.annotate, thresholds)
        gt_thresholds, synth_thresholds = thresholds_of
        w, res = case.window, case.result
        row = score_case(system, case, params, gt_thresholds=gt_thresholds[case.role],
                         synth_thresholds=synth_thresholds[case.character])
        rows.append({"system": system.name, "fit_procedure": system.fit_procedure,
                     "synthesis_procedure": system.synthesis_procedure, "fold": fold, "session": case.held_out,
                     "condition": condition, "window": w.index, "window_start": w.start, "window_end": w.end,
                     "character": case.character, "role": case.role, "seed": case.input.seed, **row})
        motion = res.motion if res is not None and res.success else None
        if motion is not None:
            if system.produces_hands:
                pts = np.asarray(pose_features(motion).positions)
            else:  # head-only systems: the head point relative to the root (the rest of the body is still)
                pts = _metric_points(motion, True, params) - np.asarray(motion.translations, np.float64)[:, :1]
            synth_windows.setdefault(case.character, []).append(pts)
            if export_bvh and out_dir is not None:
                save_bvh(motion, Path(out_dir) / "bvh" / f"{case.held_out}_w{w.index:02d}_{case.character}_{condition}.bvh")
    out = pd.DataFrame(rows)
    if len(out):  # diversity between the windows synthesized for each character in this fold and condition
        out["diversity"] = out["character"].map(lambda c: metrics.window_diversity(synth_windows.get(c, [])))
    return out
