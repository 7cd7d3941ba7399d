"""Planting motion events around the audio segments: gestures for phonemic clauses, nods for
listener responses and the partner's hesitations (independent draws or exact quotas), spontaneous
movements away from the windows, idle kept between events of one channel, coarticulation, and the
times of posture shifts."""
from __future__ import annotations

import logging

import numpy as np

from .config import ROLES
from .conversation import Segment, _turn_starts

log = logging.getLogger(__name__)


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
    # candidate segments by their index in ``segs``
    pcs = [i for i, s in enumerate(segs) if s.role == role and s.kind == "PC"]
    lrs = [i for i, s in enumerate(segs) if s.role == role and s.kind == "LR"]
    hps = [i for i, s in enumerate(segs) if s.role == partner and s.kind == "HP"]
    a = st["attributes"]
    g_attr = {i: (a.uniform(0.75, 1.25), {k: (a.normal(0, 0.05), a.uniform(-8, 14)) for k in ("LH", "RH")})
              for i in pcs}
    n_attr = {i: (a.uniform(0.1, 0.3), a.normal(0, 0.04), a.uniform(0.8, 1.2), int(a.integers(1, 4)))
              for i in lrs + hps}

    def gesture(kind, i):
        seg = segs[i]
        amp, hands = g_attr[i]
        jitter, spread = hands[kind]
        dur = float(np.clip(seg.end - seg.start, 0.6, 1.5))
        peak = seg.peak + jitter
        start = max(seg.start - 0.1, peak - 0.45 * dur)
        end = start + dur
        return {"kind": kind, "start": start, "peak": peak, "end": end, "amp": amp,
                "spread": spread, "source": seg.kind, "cause_start": seg.start}

    def nod(i):
        seg = segs[i]
        extra, jitter, amp, cycles = n_attr[i]
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
    causes = dict(zip(pcs, pc_cat))
    causes.update({i: 0 if n else -1 for i, n in zip(lrs, lr_nod)})
    causes.update({i: 0 if n else -1 for i, n in zip(hps, hp_nod)})
    for i, seg in enumerate(segs):
        cat = causes.get(i, -1)
        if seg.kind == "PC" and seg.role == role:
            if cat in (0, 1):
                events.append(gesture("LH", i))
            if cat in (0, 2):
                events.append(gesture("RH", i))
        elif cat == 0:
            events.append(nod(i))

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
                free = [i for i in pool if segs[i].start not in have]
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
