"""Parameters of the statistics (paper Section 5, Table 1; Section 7, Figure 6); ``conf/stats``."""
from __future__ import annotations

from dataclasses import dataclass

from ..errors import ConfigError

CHANCE_BASELINES = ("away", "shifted")
CHANCE_FALLBACKS = ("shifted", "none")


@dataclass(frozen=True)
class StatsParams:
    n_permutations: int = 5000   # permutation test of audio windows vs random windows
    chance_windows: int = 1      # random windows per audio window for the chance baseline
    significance: float = 0.03   # Figure 6 marks comparisons with p below this (the paper's star)
    # Chance baseline of Table 1: "away" = random windows placed away from the channel's audio segments
    # (the paper's "random windows"); "shifted" (ours) = each audio window moved to a random other time of
    # the same recording, wherever speech is.
    chance_baseline: str = "away"
    # When the baseline places no window for a row (continuous speech leaves no room away from the
    # segments): "shifted" (ours) uses shifted windows for that row; "none" reports no baseline (empty
    # p-values and a warning). The row's ``chance_method`` column says which baseline it used.
    chance_fallback: str = "shifted"
    confidence: float = 0.95     # level of the Wilson intervals on rates (Table 1, leave-one-out summaries)

    def __post_init__(self):
        if self.chance_baseline not in CHANCE_BASELINES:
            raise ConfigError(f"unknown chance baseline {self.chance_baseline!r}; expected one of {CHANCE_BASELINES}",
                              where="stats.chance_baseline")
        if self.chance_fallback not in CHANCE_FALLBACKS:
            raise ConfigError(f"unknown chance fallback {self.chance_fallback!r}; expected one of {CHANCE_FALLBACKS}",
                              where="stats.chance_fallback")
        if not 0.0 < float(self.confidence) < 1.0:
            raise ConfigError(f"confidence must lie in (0, 1), got {self.confidence}", where="stats.confidence")
