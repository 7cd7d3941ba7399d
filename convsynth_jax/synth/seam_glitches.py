"""Which seams of a synthesized path can show a planted marker-swap glitch (ours; the analysis of
docs/decisions.md#marker-swap-glitches-and-touching-clauses, run over a leave-one-out sweep by
``seam_glitches.py``, a diagnosis since retired, in git at e1848f1).

A seam is a synthetic transition arriving at output frame t. Around it the realization shows the raw
sources of output frames t - B .. t + B - 1 (B: the blend's length; the end of the clip the path
leaves and the start of the new one) and the continuation of the left clip that the blend fades out,
frames f + 1 .. f + L of the clip played at t - 1 (frame f). L spans the blend and every blend nested
into it (a transition arriving before the previous blend ended, :func:`nested_span`), so it is never
shorter than what the realization shows. The continuation is read twice: ``nominal`` (all L frames, up
to the clip's end) and ``played`` (stopped where the realization holds it,
:func:`~convsynth_jax.synth.realize.continuation_end` with ``synth.continuation_max_step_deg``; the
same as nominal when that is 0). A seam touches a glitch when any of those frames is a planted glitch
frame of its source clip (``glitches.csv`` of the synthetic corpus, :func:`glitch_frames`).
:func:`touching_rows` places every such glitch frame relative to its seam and says whether the seam
measure (``evaluation.metrics.seam_ratio``) reads it.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import pandas as pd

from ..errors import MissingFileError
from .realize import continuation_end

GLITCH_COLUMNS = ("session", "participant", "start_frame", "end_frame")


def glitch_frames(path: str | Path, clip_name: Callable[[str, str], str]) -> dict:
    """clip name (``clip_name(session, participant)``) -> set of planted glitch frames
    (start_frame <= frame < end_frame), from a synthetic corpus's ``glitches.csv`` at ``path``."""
    path = Path(path)
    if not path.is_file():
        raise MissingFileError(f"{path}: no glitches.csv (the synthetic corpus writes one; other corpora plant none)")
    table = pd.read_csv(path)
    missing = [c for c in GLITCH_COLUMNS if c not in table.columns]
    if missing:
        raise MissingFileError(f"{path}: glitches.csv lacks the columns {missing} (has {list(table.columns)})")
    out: dict = {}
    for r in table.itertuples():
        out.setdefault(clip_name(r.session, r.participant), set()).update(range(int(r.start_frame), int(r.end_frame)))
    return out


def nested_span(syn: Sequence[int], m: int, blend: int) -> int:
    """Output frames from transition ``m`` (an index into the sorted transition frames ``syn``) on
    during which the old stream of its blend can still show: its own blend, extended by every
    transition arriving before the running blend ended."""
    end = syn[m] + blend
    for t in syn[m + 1:]:
        if t >= end:
            break
        end = t + blend
    return end - syn[m]


def window_seam_glitches(result, motions: dict, glitches: dict, max_step_deg: float,
                         seam_ratio: Callable[[int], float] | None = None) -> tuple[list, int]:
    """(one dict per seam, output frames whose raw source is a glitch frame) of one synthesized window.

    ``result``: a ``WindowResult`` of a motion-graph system (``source_clip``, ``source_frame``,
    ``synthetic_at``, ``blend_frames``); ``motions``: clip name -> ``Motion`` of the sources;
    ``glitches``: :func:`glitch_frames`; ``max_step_deg``: ``synth.continuation_max_step_deg``.
    ``seam_ratio``: t -> the seam measure at output frame t, written as each seam's ``seam_ratio``
    after ``t`` (called only for a window with seams)."""
    clips, frames = list(result.source_clip), [int(f) for f in result.source_frame]
    T, B = len(frames), int(result.blend_frames)
    from_glitch = sum(f in glitches.get(c, ()) for c, f in zip(clips, frames))
    syn = sorted({int(t) for t in (result.synthetic_at or []) if 0 < int(t) < T})
    out = []
    for m, t in enumerate(syn):
        raw = [(clips[u], frames[u]) for u in range(max(0, t - B), min(T, t + B))]
        c, f = clips[t - 1], frames[t - 1]
        rot = motions[c].rotations
        span = nested_span(syn, m, B)
        nominal_end = min(rot.shape[0] - 1, f + span)
        played_end = min(nominal_end, continuation_end(rot, f, max_step_deg, span))
        g_raw = sorted({(cc, ff) for cc, ff in raw if ff in glitches.get(cc, ())})
        g_nom = sorted(ff for ff in range(f + 1, nominal_end + 1) if ff in glitches.get(c, ()))
        g_play = sorted(ff for ff in range(f + 1, played_end + 1) if ff in glitches.get(c, ()))
        row = {"t": t} if seam_ratio is None else {"t": t, "seam_ratio": seam_ratio(t)}
        out.append({**row, "left_clip": c, "left_frame": f, "new_clip": clips[t], "new_frame": frames[t],
                    "continuation_nominal_end": nominal_end, "continuation_played_end": played_end,
                    "glitch_raw": ";".join(f"{cc}:{ff}" for cc, ff in g_raw),
                    "glitch_continuation_nominal": ";".join(map(str, g_nom)),
                    "glitch_continuation_played": ";".join(map(str, g_play)),
                    "touches_glitch_nominal": bool(g_raw or g_nom), "touches_glitch_played": bool(g_raw or g_play)})
    return out, from_glitch


def _listed(cell) -> list:
    return [] if pd.isna(cell) or cell == "" else [x for x in str(cell).split(";") if x]


def touching_rows(seams: pd.DataFrame, blend: int, radius: int) -> list[dict]:
    """Each seam whose blend span touches a glitch (rows of :func:`window_seam_glitches` with ``fold``,
    ``condition``, ``character``, ``window`` and ``seam_ratio``), with every glitch frame's place: the
    output frame offset from the transition (u - t; None where another transition of the window lies
    between, so the offset is not known from the seam table) and whether the seam measure reads it (its
    accelerations at |u - t| <= ``radius`` are central differences, so they read |u - t| <= radius + 1).
    ``raw after t``: the new clip's own frames, played by the path at the blend's new-source weight;
    ``raw before t``: the left clip's frames before the transition; ``continuation``: the left clip's
    continuation faded out by the blend."""
    out = []
    keys = ["fold", "condition", "character", "window"]
    for _, s in seams[seams["touches_glitch_nominal"] | seams["touches_glitch_played"]].iterrows():
        ts = sorted(seams.loc[(seams[keys] == s[keys]).all(axis=1), "t"])
        t = int(s["t"])
        places = []
        for item in _listed(s["glitch_raw"]):
            clip, ff = item.rsplit(":", 1)
            ff = int(ff)
            if clip == s["new_clip"] and 0 <= ff - int(s["new_frame"]) < blend:
                k = ff - int(s["new_frame"])
                known = not any(t < x <= t + k for x in ts)
                places.append(("raw after t", clip, ff, k if known else None))
            elif clip == s["left_clip"] and 0 <= int(s["left_frame"]) - ff < blend:
                k = -(int(s["left_frame"]) - ff) - 1
                known = not any(t + k < x < t for x in ts)
                places.append(("raw before t", clip, ff, k if known else None))
            else:
                places.append(("raw", clip, ff, None))
        played = set(_listed(s["glitch_continuation_played"]))
        for ff in _listed(s["glitch_continuation_nominal"]):
            if ff in played:
                places.append(("continuation", s["left_clip"], int(ff), int(ff) - int(s["left_frame"]) - 1))
            else:
                places.append(("continuation, held (not played)", s["left_clip"], int(ff), None))
        for where, clip, ff, k in places:
            out.append({"fold": int(s["fold"]), "condition": str(s["condition"]), "character": str(s["character"]),
                        "window": int(s["window"]), "t": t, "seam_ratio": float(s["seam_ratio"]), "where": where,
                        "clip": clip, "frame": ff, "offset": k,
                        "in_seam_measure": None if k is None else bool(abs(k) <= radius + 1)})
    return out


def seam_glitch_counts(seams: pd.DataFrame) -> dict:
    """How many seams touch a glitch (played; nominal continuation), have one in their raw sources,
    and read over 1 on the seam measure."""
    ok = seams.dropna(subset=["seam_ratio"]) if len(seams) else seams
    return {
        "seams_total": int(len(seams)),
        "seams_touching_glitch_played": int(seams["touches_glitch_played"].sum()) if len(seams) else 0,
        "seams_touching_glitch_nominal": int(seams["touches_glitch_nominal"].sum()) if len(seams) else 0,
        "seams_with_glitch_in_raw_sources": int((seams["glitch_raw"] != "").sum()) if len(seams) else 0,
        "seams_over_1": int((ok["seam_ratio"] > 1).sum()) if len(ok) else 0,
    }

