"""Objective evaluation of Sec. V and VIII (float64 NumPy/SciPy/statsmodels, outside jit).

* :func:`cca` first canonical correlation of two multivariate series (CCA_m: original vs synthesized
  motion; CCA_ms: speech vs synthesized motion), computed per turn and averaged (Sec. VIII-A);
* :func:`gaussian_kld` KL(original || synthesized) of Gaussians fitted to the pooled frames (our
  reading of the KLD of Tables IV-V: the paper does not say how the distributions are estimated);
* :func:`loglik_rate` log P(O | lambda) / T (the LLR of Sec. VIII-A);
* :func:`constraint_tests` Sec. V: KS normality per group, Kruskal-Wallis across constraints and
  pairwise Dunn tests with Sidak correction (statsmodels' multipletests);
* :func:`gesture_classifier` an objective stand-in for the paper's human judgement of Table VI: a
  nearest-centroid classifier on the log SD of band-passed pitch and yaw, fitted on original
  nod/shake/other segments and applied to synthesized ones (ours).
"""
from __future__ import annotations

import numpy as np
from scipy import stats

from ..stats.cca import fit_cca
from .cdbn import gaussian_kl


def cca(x: np.ndarray, y: np.ndarray, reg: float = 1e-6) -> float:
    """First canonical correlation of x (T, p) and y (T, q) (:func:`convsynth_jax.stats.cca.fit_cca`, the
    project's one CCA; ``reg``: its ridge, relative to each block's mean variance); NaN under 3 frames."""
    if len(x) < 3:
        return float("nan")
    return fit_cca(x, y, reg).rho


def gaussian_kld(original: np.ndarray, synthesized: np.ndarray, floor: float = 1e-2) -> float:
    """KL(N_original || N_synthesized) of Gaussians fitted to the frames (T, d) (z-units); ``floor`` is
    added to both covariances' diagonals (ours: a nearly constant synthesized angle would otherwise
    make the divergence arbitrarily large)."""
    o, s = np.asarray(original, np.float64), np.asarray(synthesized, np.float64)
    d = o.shape[1]
    co = np.cov(o.T) + floor * np.eye(d)
    cs = np.cov(s.T) + floor * np.eye(d)
    return gaussian_kl(o.mean(0), co, s.mean(0), cs)


def band_sd(angles: np.ndarray, fps: float, seconds: float = 0.5) -> np.ndarray:
    """SD of each angle after removing a moving average of ``seconds`` (keeps nod/shake-rate motion)."""
    k = max(3, int(seconds * fps) | 1)
    ker = np.ones(k) / k
    out = []
    for c in range(angles.shape[1]):
        a = angles[:, c]
        pad = np.pad(a, k // 2, mode="edge")
        out.append(np.std(a - np.convolve(pad, ker, mode="valid")))
    return np.asarray(out)


class NearestCentroid:
    def __init__(self, feats: np.ndarray, labels: np.ndarray):
        self.classes = np.unique(labels)
        self.centroids = np.stack([feats[labels == c].mean(0) for c in self.classes])
        self.scale = feats.std(0) + 1e-9

    def predict(self, feats: np.ndarray) -> np.ndarray:
        d = (((feats[:, None, :] - self.centroids[None]) / self.scale) ** 2).sum(-1)
        return self.classes[np.argmin(d, axis=1)]


def gesture_features(angles: np.ndarray, fps: float) -> np.ndarray:
    """log band SD of pitch and yaw of one segment (pitch, yaw, roll degrees) -> (2,)."""
    sd = band_sd(angles, fps)
    return np.log(sd[:2] + 1e-3)


def gesture_classifier(segments: list[np.ndarray], labels: list[str], fps: float) -> NearestCentroid:
    return NearestCentroid(np.stack([gesture_features(s, fps) for s in segments]), np.asarray(labels))


def dunn_sidak(groups: list[np.ndarray]) -> list[tuple[int, int, float]]:
    """Dunn's pairwise test on pooled ranks (tie-corrected), p-values Sidak-corrected."""
    from statsmodels.stats.multitest import multipletests

    data = np.concatenate(groups)
    ranks = stats.rankdata(data)
    n = len(data)
    sizes = [len(g) for g in groups]
    offs = np.cumsum([0] + sizes)
    mean_r = [ranks[offs[i]:offs[i + 1]].mean() for i in range(len(groups))]
    _, counts = np.unique(data, return_counts=True)
    tie = (counts ** 3 - counts).sum() / (12.0 * (n - 1))
    pairs, ps = [], []
    for i in range(len(groups)):
        for j in range(i + 1, len(groups)):
            se = np.sqrt((n * (n + 1) / 12.0 - tie) * (1.0 / sizes[i] + 1.0 / sizes[j]))
            z = (mean_r[i] - mean_r[j]) / se
            pairs.append((i, j))
            ps.append(2 * stats.norm.sf(abs(z)))
    adj = multipletests(ps, method="sidak")[1] if ps else []
    return [(i, j, float(p)) for (i, j), p in zip(pairs, adj)]


def constraint_tests(values: np.ndarray, codes: np.ndarray, names: tuple, alpha: float = 0.05,
                     max_per_group: int = 5000, seed: int = 0) -> dict:
    """Sec. V for one variable (e.g. head pitch): KS normality per constraint (on z-scored values),
    Kruskal-Wallis across constraints, Dunn-Sidak pairs when KW rejects. Groups are subsampled to
    ``max_per_group`` frames (frames are serially correlated; the paper does not thin them either)."""
    rng = np.random.default_rng(seed)
    groups, used = [], []
    for k, n in enumerate(names):
        g = np.asarray(values)[np.asarray(codes) == k]
        if len(g) > max_per_group:
            g = rng.choice(g, max_per_group, replace=False)
        if len(g) >= 3:
            groups.append(g)
            used.append(n)
    out = {"groups": used, "ks_p": {}, "kruskal_p": float("nan"), "pairs": []}
    for n, g in zip(used, groups):
        z = (g - g.mean()) / max(g.std(), 1e-12)
        out["ks_p"][n] = float(stats.kstest(z, "norm").pvalue)
    if len(groups) >= 2:
        out["kruskal_p"] = float(stats.kruskal(*groups).pvalue)
        if out["kruskal_p"] < alpha:
            out["pairs"] = [{"a": used[i], "b": used[j], "p": p, "significant": p < alpha}
                            for i, j, p in dunn_sidak(groups)]
    return out
