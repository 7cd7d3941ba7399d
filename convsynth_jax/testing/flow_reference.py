"""Slow, obvious references for the flow-matching model's kernels (tests only)."""
from __future__ import annotations

import numpy as np


def dilated_conv_loop(h: np.ndarray, kernel: np.ndarray, bias: np.ndarray, dilation: int) -> np.ndarray:
    """A 'same'-padded dilated 1-D convolution by loops: h (B, T, C), kernel (k, C, O) -> (B, T, O);
    tap i of frame t reads frame t + (i - (k - 1) // 2) * dilation (zero outside)."""
    B, T, C = h.shape
    k, _, O = kernel.shape
    half = (k - 1) // 2
    out = np.zeros((B, T, O))
    for b in range(B):
        for t in range(T):
            acc = np.array(bias, np.float64)
            for i in range(k):
                s = t + (i - half) * dilation
                if 0 <= s < T:
                    acc = acc + np.asarray(h[b, s], np.float64) @ np.asarray(kernel[i], np.float64)
            out[b, t] = acc
    return out


def mixture_sample(rng: np.random.Generator, n: int, means: np.ndarray, sd: float, weights: np.ndarray) -> np.ndarray:
    """n draws of an isotropic Gaussian mixture (the toy distribution of the objective's check)."""
    comp = rng.choice(len(weights), size=n, p=weights)
    return means[comp] + sd * rng.normal(size=(n, means.shape[1]))
