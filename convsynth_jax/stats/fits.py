"""Distribution fits for the transition-cost threshold (paper Section 6, Figure 4).

Each candidate scipy.stats distribution is fitted by maximum likelihood to (a subsample of) the
costs; the residual sum of squares between its pdf and the normalized histogram ranks the fits.

Support: Johnson SB and beta get a bounded support fixed just around the data (loc slightly below
the minimum, scale slightly above the range); gamma, lognorm, weibull_min and expon get loc fixed at
0 (or just below the minimum if it is negative); Johnson SU is fitted with all four parameters.
With loc and scale fixed, the Johnson SB maximum-likelihood shapes have a closed form
(z = log(y / (1 - y)) is normal: b = 1 / std(z), a = -mean(z) b), used instead of a numerical fit.
Johnson SU (a numerical 4-parameter fit, the slow one) uses at most ``slow_max_samples`` values.
"""
from __future__ import annotations

import warnings
from typing import NamedTuple

import numpy as np
import pandas as pd
from scipy import stats

from ..errors import ConfigError, ConvSynthError

CANDIDATES = ("johnsonsb", "gamma", "lognorm", "weibull_min", "beta", "johnsonsu", "expon")


class FitResult(NamedTuple):
    table: pd.DataFrame          # distribution, params, rss, sorted by rss
    chosen: str
    params: tuple
    bin_edges: np.ndarray
    density: np.ndarray

    def frozen(self, name: str | None = None):
        name = name or self.chosen
        row = self.table.set_index("distribution").loc[name]
        return getattr(stats, name)(*row["params"])

    def quantile(self, q: float, name: str | None = None) -> float:
        return float(self.frozen(name).ppf(q))


def johnsonsb_mle(x: np.ndarray, loc: float, scale: float) -> tuple:
    """Maximum-likelihood (a, b, loc, scale) of Johnson SB with loc and scale fixed (closed form).
    Every x must lie strictly inside (loc, loc + scale)."""
    y = (np.asarray(x, np.float64) - loc) / scale
    if not (np.all(y > 0) and np.all(y < 1)):
        raise ValueError("values outside the fixed Johnson SB support")
    z = np.log(y / (1.0 - y))
    sd = float(np.std(z))
    if not sd > 0:
        raise ValueError("degenerate sample for Johnson SB")
    b = 1.0 / sd
    return (-float(np.mean(z)) * b, b, float(loc), float(scale))


def fit_distributions(x: np.ndarray, candidates=CANDIDATES, bins: int = 100, max_samples: int = 20000,
                      seed: int = 0, choose: str = "johnsonsb", slow_max_samples: int = 4000) -> FitResult:
    """Fit ``candidates`` (scipy.stats names) to ``x`` (n,) and rank them by the residual sum of
    squares between the fitted pdf at the bin centres and the density-normalized histogram with
    ``bins`` bins. ``choose``: a candidate name (forced), or ``"auto"`` for the lowest RSS.
    Returns the table (distribution, params, rss; sorted by rss), the chosen name and params, and
    the histogram (bin edges, density)."""
    x = np.asarray(x, dtype=np.float64)
    x = x[np.isfinite(x)]
    if x.size < 10:
        raise ConvSynthError(f"need at least 10 finite values to fit a distribution, got {x.size}",
                             where="transition-cost distribution fit")
    density, edges = np.histogram(x, bins=bins, density=True)
    centres = 0.5 * (edges[1:] + edges[:-1])
    rng = np.random.default_rng(seed)
    sample = rng.choice(x, size=min(max_samples, x.size), replace=False)
    lo, hi = float(x.min()), float(x.max())
    span = max(hi - lo, 1e-9)
    rows = []
    for name in candidates:
        dist = getattr(stats, name)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                if name == "johnsonsb":
                    params = johnsonsb_mle(sample, lo - 1e-3 * span, span * 1.002)
                elif name == "beta":  # bounded support: fix it just around the data
                    params = dist.fit(sample, floc=lo - 1e-3 * span, fscale=span * 1.002)
                elif name in ("gamma", "lognorm", "weibull_min", "expon"):
                    params = dist.fit(sample, floc=min(0.0, lo - 1e-6))
                else:
                    params = dist.fit(sample[:slow_max_samples])
                pdf = dist.pdf(centres, *params)
            rss = float(np.sum((pdf - density) ** 2)) if np.all(np.isfinite(pdf)) else np.inf
        except Exception:  # a failed fit just ranks last
            params, rss = (), np.inf
        rows.append({"distribution": name, "params": tuple(float(p) for p in params), "rss": rss})
    table = pd.DataFrame(rows).sort_values("rss", kind="stable").reset_index(drop=True)
    chosen = table["distribution"].iat[0] if choose == "auto" else choose
    if chosen not in set(table["distribution"]):
        raise ConfigError(f"distribution {chosen!r} is not one of auto, {', '.join(candidates)}",
                          where="graph.distribution")
    params = table.set_index("distribution").loc[chosen, "params"]
    if not params:
        raise ConvSynthError(f"fitting {chosen} to {x.size} costs failed", where="transition-cost distribution fit")
    return FitResult(table, chosen, params, edges, density)
