"""Parameters of the statistics (paper Section 5, Table 1; Section 7, Figure 6); ``conf/stats``."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class StatsParams:
    n_permutations: int = 5000   # permutation test of audio windows vs random windows
    chance_windows: int = 1      # random windows per audio window for the chance baseline
    significance: float = 0.03   # Figure 6 marks comparisons with p below this (the paper's star)
