"""One session's plan (conversation and planted movements, deterministic in the seed, the session
index and the planting probabilities) and the rendering of its motion."""
from __future__ import annotations

import numpy as np

from ...skeleton import Motion
from .config import EMOTIONS, ROLES
from .conversation import _session_start
from .motion import _motion
from .planting import _plant_events, _shift_times


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
