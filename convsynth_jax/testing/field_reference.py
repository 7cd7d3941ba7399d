"""Slow, obvious references of the field-standard metrics (``convsynth_jax.evaluation.field``):
plain loops over frames, joints and beats, written from the definitions and sharing no code with
the library. Tests compare both on random and real windows; the tolerances live here.
"""
from __future__ import annotations

import math

import numpy as np

RTOL = 1e-9      # float64 loops vs vectorised float64
CCA_ATOL = 1e-4  # our closed-form CCA vs scikit-learn's iterative one (first canonical correlation)
FGD_RTOL = 1e-6  # scipy's Schur square root vs the symmetric eigen route


def average_derivative_loop(positions, fps, order):
    p = np.asarray(positions, float)
    F, J, _ = p.shape
    per_joint = []
    for j in range(J):
        vals = []
        for f in range(F - order):
            d = np.zeros(3)
            for k in range(order + 1):   # the order-th forward difference by its binomial sum
                d += (-1) ** (order - k) * math.comb(order, k) * p[f + k, j]
            vals.append(math.sqrt(float(d @ d)) * fps ** order)
        per_joint.append(sum(vals) / len(vals))
    return sum(per_joint) / len(per_joint)


def histogram_loop(values, bin_width, max_value):
    nbins = int(math.ceil(max_value / bin_width - 1e-9))
    counts = [0.0] * (nbins + 1)
    for v in np.asarray(values, float).ravel():
        k = int(math.floor(v / bin_width))
        counts[min(max(k, 0), nbins)] += 1
    return np.array(counts)


def hellinger_loop(p, q):
    """(1 / sqrt 2) ||sqrt p - sqrt q||_2 of the normalised histograms (the same distance, another form)."""
    sp, sq = sum(p), sum(q)
    s = 0.0
    for a, b in zip(p, q):
        s += (math.sqrt(a / sp) - math.sqrt(b / sq)) ** 2
    return math.sqrt(s / 2.0)


def frechet_loop(features_a, features_b):
    """Fréchet distance with the square root of S1 by a symmetric eigendecomposition:
    tr (S1 S2)^(1/2) = tr (S1^(1/2) S2 S1^(1/2))^(1/2)."""
    a, b = np.asarray(features_a, float), np.asarray(features_b, float)
    mu1, mu2 = a.mean(0), b.mean(0)
    s1 = sum(np.outer(x - mu1, x - mu1) for x in a) / (len(a) - 1)
    s2 = sum(np.outer(x - mu2, x - mu2) for x in b) / (len(b) - 1)
    w, v = np.linalg.eigh(s1)
    r1 = (v * np.sqrt(np.clip(w, 0, None))) @ v.T
    m = r1 @ s2 @ r1
    tr = float(np.sum(np.sqrt(np.clip(np.linalg.eigvalsh((m + m.T) / 2), 0, None))))
    d = mu1 - mu2
    return max(0.0, float(d @ d + np.trace(s1) + np.trace(s2) - 2 * tr))


def beat_consistency_loop(positions, fps, audio_beats, duration, sigma, order, threshold, trim):
    p = np.asarray(positions, float)
    F, J, _ = p.shape
    scores = []
    audio = [t for t in audio_beats if trim <= t <= duration - trim]
    if not audio:
        return float("nan")
    for j in range(J):
        speed = []
        for f in range(F):
            a, b = (f - 1, f + 1) if 0 < f < F - 1 else ((0, 1) if f == 0 else (F - 2, F - 1))
            step = (b - a)
            d = (p[b, j] - p[a, j]) / step
            speed.append(math.sqrt(float(d @ d)) * fps)
        mean = sum(speed) / F
        if mean <= 0:
            continue
        r = [s / mean for s in speed]
        beats = []
        for f in range(F):
            lo, hi = f - order, f + order
            if lo < 0 or hi >= F:   # a minimum needs order frames on both sides (argrelextrema's clip mode compares with the edge)
                neigh = [r[g] for g in range(max(lo, 0), min(hi, F - 1) + 1) if g != f]
                neigh += [r[0]] * (max(0, -lo)) + [r[F - 1]] * max(0, hi - (F - 1))
            else:
                neigh = [r[g] for g in range(lo, hi + 1) if g != f]
            if all(r[f] < x for x in neigh) and r[f] > threshold:
                t = f / fps
                if trim <= t <= duration - trim:
                    beats.append(t)
        if not beats:
            continue
        s = 0.0
        for t in beats:
            d = min(abs(t - a) for a in audio)
            s += math.exp(-d * d / (2 * sigma * sigma))
        scores.append(s / len(beats))
    return sum(scores) / len(scores) if scores else float("nan")


def l1_diversity_loop(relative):
    x = np.asarray(relative, float).reshape(len(relative), -1)
    mean = [sum(x[:, d]) / len(x) for d in range(x.shape[1])]
    total = 0.0
    for t in range(len(x)):
        total += sum(abs(x[t, d] - mean[d]) for d in range(x.shape[1]))
    return total / len(x)


def covered_cells_loop(relative, parents, cell, axes=(0, 1)):
    p = np.asarray(relative, float)
    longest = 0.0
    for f in range(len(p)):
        for j, q in enumerate(parents):
            if q >= 0:
                longest = max(longest, float(np.linalg.norm(p[f, j, list(axes)] - p[f, q, list(axes)])))
    n = int(math.ceil(longest / (0.5 * cell))) + 1
    cells = set()
    for f in range(len(p)):
        for j, q in enumerate(parents):
            if q < 0:
                continue
            a, b = p[f, q, list(axes)], p[f, j, list(axes)]
            for k in range(n):
                t = k / (n - 1) if n > 1 else 0.0
                pt = a + t * (b - a)
                cells.add((math.floor(pt[0] / cell), math.floor(pt[1] / cell)))
    return cells


def dice_loop(cells_a, cells_b):
    if not cells_a and not cells_b:
        return float("nan")
    return 2 * len(cells_a & cells_b) / (len(cells_a) + len(cells_b))


def still_frames_loop(positions, fps, threshold):
    """Still frames by loops: each joint's step to the next frame (the last frame: the step into it),
    its length times fps, mean over joints, below the threshold."""
    F, J = len(positions), len(positions[0])
    out = []
    for t in range(F):
        if F < 2:
            out.append(False)
            continue
        a, b = (t, t + 1) if t + 1 < F else (t - 1, t)
        total = 0.0
        for j in range(J):
            d = [positions[b][j][k] - positions[a][j][k] for k in range(3)]
            total += math.sqrt(sum(x * x for x in d)) * fps
        out.append(total / J < threshold)
    return out
