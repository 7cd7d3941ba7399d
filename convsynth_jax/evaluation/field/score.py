"""Scoring many systems on the same windows: per-window rows and set-level metrics with
session-level bootstrap intervals (the library half of ``convsynth task=benchmark``).

Per window (one row per window x character x system x scope): average jerk and acceleration,
Hellinger distances of its speed and acceleration histograms to the ground truth window's, beat
consistency with the window's own audio, L1 diversity, gesture area coverage (body scope), and the
window's CCA_m / CCA_ms correlations under the one CCA fitted on all of the system's windows.
Per set (a system in a scope): FGD on raw windows and on each autoencoder's codes against the
ground truth's windows, the pooled CCA_m / CCA_ms, the Hellinger distance of the pooled histograms.

Set-level metrics are computed from per-session moments (counts, sums, sums of outer products), so
the bootstrap resamples sessions (the held-out folds) with replacement, windows of one session
staying together: windows of one conversation are not independent.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, Optional

import numpy as np
import pandas as pd

from . import beat, coverage, kinematic
from .autoencoder import TrainedAutoencoder, encode_many
from .cca import cca_from_covariances, correlation_from_moments
from .fgd import frechet_distance, frechet_distance_eig, raw_window_features, sqrt_psd
from .params import FieldMetricParams
from .views import MotionView

log = logging.getLogger(__name__)

# metric -> how systems are ranked: "low" (smaller is better), "high", or "gt" (closest to the
# ground truth's own value)
DIRECTION = {
    "jerk": "gt", "acceleration": "gt", "hellinger_speed": "low", "hellinger_acceleration": "low",
    "beat_consistency": "high", "l1_diversity": "gt", "gac": "high", "cca_m": "high", "cca_ms": "high",
    "fgd_raw": "low", "cca_m_set": "high", "cca_ms_set": "high", "hellinger_speed_set": "low",
    "hellinger_acceleration_set": "low",
}
SPEECH_DIM = 4   # cca.speech_cca_features: F0, energy and their derivatives
WINDOW_METRICS = ("jerk", "acceleration", "hellinger_speed", "hellinger_acceleration", "beat_consistency",
                  "l1_diversity", "gac", "cca_m", "cca_ms")


class _Moments:
    """Running n, sum and sum of outer products of row vectors."""

    def __init__(self):
        self.n, self.s, self.ss = 0.0, None, None

    def add(self, x: np.ndarray) -> None:
        x = np.asarray(x, np.float64).reshape(len(x), -1)
        if not len(x):
            return
        if self.s is None:
            self.s, self.ss = np.zeros(x.shape[1]), np.zeros((x.shape[1], x.shape[1]))
        self.n += len(x)
        self.s += x.sum(0)
        self.ss += x.T @ x

    def tuple(self):
        return (self.n, self.s, self.ss)


def _pool(parts: list) -> tuple[float, Any, Any]:
    """Sum of (n, s, ss) moment tuples with weights: parts = [(w, (n, s, ss)), ...]."""
    n, s, ss = 0.0, None, None
    for w, (pn, ps, pss) in parts:
        if ps is None or w == 0:
            continue
        n += w * pn
        s = w * ps if s is None else s + w * ps
        ss = w * pss if ss is None else ss + w * pss
    return n, s, ss


def _gauss(n, s, ss):
    mu = s / n
    cov = (ss - n * np.outer(mu, mu)) / max(n - 1.0, 1.0)
    return mu, cov


@dataclass
class SetMoments:
    """Per-session moments of one system in one scope (session -> values)."""

    raw: Dict[str, _Moments] = field(default_factory=dict)           # raw-window features
    ae: Dict[int, Dict[str, _Moments]] = field(default_factory=dict)  # window -> session -> codes
    cca_m: Dict[str, _Moments] = field(default_factory=dict)          # [gt, system] per frame
    cca_ms: Dict[str, _Moments] = field(default_factory=dict)         # [speech, system] per frame
    hist: Dict[str, Dict[str, np.ndarray]] = field(default_factory=dict)  # session -> kind -> counts
    window_cca: list = field(default_factory=list)                    # (row index, cca_m moments, cca_ms moments)


def _get(d: dict, k, make):
    if k not in d:
        d[k] = make()
    return d[k]


def score_window(view: MotionView, gt: MotionView, audio_beats: Optional[np.ndarray], speech: Optional[np.ndarray],
                 fps: float, duration: float, params: FieldMetricParams, scope: str, moments: SetMoments,
                 session: str, gt_cells: Optional[np.ndarray] = None) -> dict:
    """The per-window metrics of one system's window against its ground truth window, adding the
    window's contributions to the set's moments (the autoencoder codes are added in batches by
    :func:`add_codes`). ``gt_cells``: the ground truth window's covered cells, when already known."""
    hp = params.histogram
    n = min(len(view.relative), len(gt.relative))
    row = {"jerk": kinematic.average_jerk(view.global_positions, fps),
           "acceleration": kinematic.average_acceleration(view.global_positions, fps)}
    h, hg = (kinematic.motion_histograms(v.global_positions, fps, hp) for v in (view, gt))
    row["hellinger_speed"] = kinematic.hellinger(h["speed"], hg["speed"])
    row["hellinger_acceleration"] = kinematic.hellinger(h["acceleration"], hg["acceleration"])
    hs = _get(moments.hist, session, lambda: {"speed": 0.0, "acceleration": 0.0})
    hs["speed"] = hs["speed"] + h["speed"]
    hs["acceleration"] = hs["acceleration"] + h["acceleration"]
    if audio_beats is not None:
        mb = beat.motion_beats(view.relative[:, list(view.upper)], fps, params.beat)
        row["beat_consistency"] = beat.beat_consistency(mb, audio_beats, duration, params.beat)
    else:
        row["beat_consistency"] = float("nan")
    row["l1_diversity"] = coverage.l1_diversity(view.relative)
    if scope == "body":
        if gt_cells is None:
            gt_cells = coverage.covered_cells(gt.relative, gt.parents, params.coverage)
        row["gac"] = coverage.dice(coverage.covered_cells(view.relative, view.parents, params.coverage), gt_cells)
    else:
        row["gac"] = float("nan")
    fp = params.fgd
    _get(moments.raw, session, _Moments).add(raw_window_features(view.relative, fp.raw_window_frames, fp.raw_frame_step))
    # CCA moments of frames centred within the window: the pooled fit then measures how the streams
    # move together inside windows, not how window averages differ (which would lift any pairing)
    x = view.relative[:n].reshape(n, -1)
    z = np.concatenate([gt.relative[:n].reshape(n, -1), x], axis=1)
    z = z - z.mean(axis=0)
    wm = _Moments()
    wm.add(z)
    _get(moments.cca_m, session, _Moments).add(z)
    ws = None
    if speech is not None:
        k = min(n, len(speech))
        ws = _Moments()
        z = np.concatenate([speech[:k], x[:k]], axis=1)
        z = z - z.mean(axis=0)
        ws.add(z)
        _get(moments.cca_ms, session, _Moments).add(z)
    row["_cca"] = (wm.tuple(), None if ws is None else ws.tuple())
    return row


def reference_moments(gt_views: Dict[Any, tuple], params: FieldMetricParams,
                      autoencoders: Dict[int, TrainedAutoencoder], fps: float) -> SetMoments:
    """The ground truth's set moments (raw features, codes, histograms) per session:
    gt_views: case id -> (session, MotionView)."""
    m = SetMoments()
    fp = params.fgd
    add_codes(m, [(s, v.relative) for s, v in gt_views.values()], autoencoders)
    for session, v in gt_views.values():
        _get(m.raw, session, _Moments).add(raw_window_features(v.relative, fp.raw_window_frames, fp.raw_frame_step))
        h = kinematic.motion_histograms(v.global_positions, fps, params.histogram)
        hs = _get(m.hist, session, lambda: {"speed": 0.0, "acceleration": 0.0})
        hs["speed"] = hs["speed"] + h["speed"]
        hs["acceleration"] = hs["acceleration"] + h["acceleration"]
    return m


def add_codes(moments: SetMoments, sequences: list, autoencoders: Dict[int, TrainedAutoencoder]) -> None:
    """Add the autoencoder codes of ``sequences`` ([(session, relative (F, P, 3))]) to ``moments``,
    encoded in shared batches."""
    for w, ae in autoencoders.items():
        for (session, _), codes in zip(sequences, encode_many(ae, [r for _, r in sequences])):
            _get(_get(moments.ae, w, dict), session, _Moments).add(codes)


def set_metrics(sys_m: SetMoments, ref_m: SetMoments, weights: Dict[str, float], params: FieldMetricParams,
                fast: bool = False, cache: Optional[dict] = None) -> dict:
    """Set-level metrics of one system from per-session moments, each session weighted by
    ``weights`` (1 each for the point estimate; bootstrap counts for a resample). ``fast``: the
    symmetric-eigenvalue form of the Fréchet distance (bootstrap resamples), with the reference's
    Gaussian and square root kept in ``cache`` (shared by the systems compared with one reference; one dict per
    reference, never shared between references)."""
    out = {}
    wkey = tuple(sorted(weights.items()))

    def fgd_of(sd: Dict[str, _Moments], rd: Dict[str, _Moments], name: str) -> float:
        ps = _pool([(weights.get(k, 0.0), v.tuple()) for k, v in sd.items()])
        if ps[0] < 2:
            return float("nan")
        ck = (name, wkey)  # one cache per reference (the caller's contract), so its name and the weights identify it
        if cache is None or ck not in cache:
            pr = _pool([(weights.get(k, 0.0), v.tuple()) for k, v in rd.items()])
            ref = None
            if pr[0] >= 2:
                mu_r, s_r = _gauss(*pr)
                ref = (mu_r, s_r, sqrt_psd(s_r) if fast else None)
            if cache is not None:
                cache[ck] = ref
        else:
            ref = cache[ck]
        if ref is None:
            return float("nan")
        mu, s = _gauss(*ps)
        if fast:
            return frechet_distance_eig(mu, s, ref[0], ref[1], ref[2])
        return frechet_distance(mu, s, ref[0], ref[1], params.fgd.eps)

    out["fgd_raw"] = fgd_of(sys_m.raw, ref_m.raw, "raw")
    for w in sorted(ref_m.ae):
        out[f"fgd_ae{w}"] = fgd_of(sys_m.ae.get(w, {}), ref_m.ae[w], f"ae{w}")
    ridge = params.cca.ridge
    for name, d in (("cca_m_set", sys_m.cca_m), ("cca_ms_set", sys_m.cca_ms)):
        n, s, ss = _pool([(weights.get(k, 0.0), v.tuple()) for k, v in d.items()])
        if n < 3 or s is None:
            out[name] = float("nan")
            continue
        _, c = _gauss(n, s, ss)
        p = c.shape[0] // 2 if name == "cca_m_set" else SPEECH_DIM
        out[name] = cca_from_covariances(c[:p, :p], c[p:, p:], c[:p, p:], ridge)[2]
    for kind in ("speed", "acceleration"):
        hs = sum(weights.get(k, 0.0) * v[kind] for k, v in sys_m.hist.items())
        hr = sum(weights.get(k, 0.0) * v[kind] for k, v in ref_m.hist.items())
        out[f"hellinger_{kind}_set"] = (kinematic.hellinger(hs, hr) if np.ndim(hs) and np.ndim(hr)
                                        else float("nan"))
    return out


def cca_weights(sys_m: SetMoments, ridge: float) -> dict:
    """The CCA_m and CCA_ms projections fitted once on all of a system's windows (pooled frames)."""
    out = {}
    for name, d, split in (("cca_m", sys_m.cca_m, None), ("cca_ms", sys_m.cca_ms, SPEECH_DIM)):
        n, s, ss = _pool([(1.0, v.tuple()) for v in d.values()])
        if n < 3 or s is None:
            continue
        _, c = _gauss(n, s, ss)
        p = c.shape[0] // 2 if split is None else split
        a, b, _ = cca_from_covariances(c[:p, :p], c[p:, p:], c[:p, p:], ridge)
        out[name] = (a, b)
    return out


def window_cca(moments_pair, weights: dict) -> dict:
    """The window's CCA_m / CCA_ms correlations under its system's fitted projections."""
    out = {"cca_m": float("nan"), "cca_ms": float("nan")}
    for name, mom in zip(("cca_m", "cca_ms"), moments_pair):
        if mom is not None and name in weights:
            out[name] = correlation_from_moments(*mom, *weights[name])
    return out


def bootstrap_intervals(values_by_session: Callable[[Dict[str, float]], dict], sessions: list, reps: int,
                        seed: int, level: float = 0.95) -> dict:
    """metric -> (low, high) percentile interval of ``values_by_session(weights)`` over ``reps``
    resamples of the sessions with replacement (weights: how often each was drawn)."""
    if reps <= 0 or len(sessions) < 2:
        return {}
    gen = np.random.default_rng(seed)
    draws: Dict[str, list] = {}
    for _ in range(reps):
        counts = np.bincount(gen.integers(0, len(sessions), len(sessions)), minlength=len(sessions))
        vals = values_by_session({s: float(c) for s, c in zip(sessions, counts)})
        for k, v in vals.items():
            draws.setdefault(k, []).append(v)
    a = (1.0 - level) / 2.0
    return {k: (float(np.nanquantile(v, a)), float(np.nanquantile(v, 1 - a))) if np.isfinite(v).any()
            else (float("nan"), float("nan")) for k, v in draws.items()}


def window_sums(rows: pd.DataFrame) -> Dict[str, tuple]:
    """session -> (sums (M,), counts (M,)) of the finite values of each of WINDOW_METRICS."""
    out = {}
    for sess, g in rows.groupby("session"):
        v = np.stack([g[m].to_numpy(np.float64) if m in g else np.full(len(g), np.nan) for m in WINDOW_METRICS], 1)
        ok = np.isfinite(v)
        out[sess] = (np.where(ok, v, 0.0).sum(0), ok.sum(0).astype(np.float64))
    return out


def window_means(sums: Dict[str, tuple], weights: Dict[str, float]) -> dict:
    """Means of the per-window metrics over windows whose session has weight w (counted w times);
    ``sums``: :func:`window_sums`."""
    tot, cnt = np.zeros(len(WINDOW_METRICS)), np.zeros(len(WINDOW_METRICS))
    for sess, (s, c) in sums.items():
        w = weights.get(sess, 0.0)
        tot += w * s
        cnt += w * c
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(cnt > 0, tot / np.maximum(cnt, 1e-300), np.nan)
    return dict(zip(WINDOW_METRICS, (float(x) for x in mean)))
