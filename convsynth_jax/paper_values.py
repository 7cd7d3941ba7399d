"""The numbers reported by Yang, Yang & Hodgins, *Statistics-based Motion Synthesis for Social
Conversations* (SCA 2020), in one place, each with the section, table or figure it comes from.

Reports put these beside the values computed from a run (``convsynth_jax.tasks.main``); nothing in
the pipeline uses them as parameters. Rates are fractions (0-1).
"""
from __future__ import annotations

# Table 1 (Section 5): audio-motion co-occurrence per actor, matched motion / total audio segments.
TABLE1 = {
    ("female", "PC-LH"): (319, 515),
    ("female", "PC-RH"): (336, 515),
    ("female", "PC-LH/RH"): (387, 515),
    ("female", "LR-Nod"): (70, 121),
    ("female", "PH-Nod"): (21, 69),
    ("male", "PC-LH"): (314, 614),
    ("male", "PC-RH"): (309, 614),
    ("male", "PC-LH/RH"): (382, 614),
    ("male", "LR-Nod"): (81, 152),
    ("male", "PH-Nod"): (14, 40),
}
TABLE1_SOURCE = "Table 1 (Section 5)"

# Table 2 (Section 6): states and edges before / after keeping the largest SCC, k -> counts.
TABLE2 = {
    2: {"states_before_scc": 50568, "edges_before_scc": 130397, "states_after_scc": 3899, "edges_after_scc": 13182},
    3: {"states_before_scc": 50568, "edges_before_scc": 408234, "states_after_scc": 40673, "edges_after_scc": 376300},
    4: {"states_before_scc": 50568, "edges_before_scc": 1823041, "states_after_scc": 47854,
        "edges_after_scc": 1810036},
}
TABLE2_SOURCE = "Table 2 (Section 6)"

# Section 6: key states are 22.25% of the states; the threshold is the 95% level of the Johnson SB
# fit to c(i, i+k) at k = 3 (Figure 4 shows the histograms and fits for k = 2..5; no numbers).
KEY_STATE_FRACTION = 0.2225
THRESHOLD_QUANTILE = 0.95
CHOSEN_K = 3
FIGURE4_SOURCE = "Figure 4 and Section 6 (Johnson SB fit, 95% level, k = 3)"

# Table 3 (Section 8.3): wall-clock seconds (mean, standard deviation), leave-one-out, i9-9980XE, <= 4 cores.
TABLE3 = {"graph construction": (47.94, 3.30), "search": (1.16, 0.56)}
TABLE3_SOURCE = "Table 3 (Section 8.3)"

# Section 8.1: leave-one-out, 15 s windows every 14 s: 116 test cases; solved with all constraints
# 81 (69.8%), without HP constraints 100 (86.2%). Other conditions: not reported.
SUCCESS = {"all": (81, 116), "no_hp": (100, 116)}
SUCCESS_SOURCE = "Section 8.1"

# Figure 6 and Section 8.2: forced-choice counts (answers preferring A, total answers) and the
# reported two-sample prop.test statistics (chi2, p); p < 0.03 is starred.
USER_STUDY = {
    "Motion capture vs all constraints": {"preferred_a": 142, "total": 206, "chi2": 57.563, "p_value": 3.272e-14},
    "All constraints vs without LR": {"preferred_a": 108, "total": 193, "chi2": 5.0155, "p_value": 0.02512},
    "All constraints vs without HP": {"preferred_a": 94, "total": 201, "chi2": 1.4328, "p_value": 0.2313},
    "All constraints vs no constraints": {"preferred_a": 116, "total": 200, "chi2": 9.61, "p_value": 0.001935},
}
USER_STUDY_SOURCE = "Figure 6 and Section 8.2"
USER_STUDY_ALPHA = 0.03

# The paper reports no co-occurrence rates of synthesized motion per ablation condition and no
# objective motion-quality metrics; its ablation is the user study above.
