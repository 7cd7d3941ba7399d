# ---
# jupyter:
#   jupytext:
#     formats: py:percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Co-occurrence analysis (paper Table 1)
# Match rates of hand gestures and nods with phonemic clauses, listener responses and partner
# hesitations, with chi-square and permutation tests against equally many random windows.

# %%
import sys
from pathlib import Path

sys.path.insert(0, str(Path.cwd()))
import matplotlib.pyplot as plt
import pandas as pd
from _paths import results_dir

table1 = pd.read_csv(results_dir() / "table1_cooccurrence.csv")
table1

# %%
fig, ax = plt.subplots(figsize=(7, 3))
for i, (char, g) in enumerate(table1.groupby("character")):
    ax.bar([j + 0.4 * i for j in range(len(g))], 100 * g["rate"], width=0.4, label=char)
ax.set_xticks([j + 0.2 for j in range(len(g))], g["hypothesis"])
ax.set_ylabel("rate (%)"); ax.legend(); fig.tight_layout()

# %%
sig = table1[["character", "hypothesis", "rate"] + [c for c in ("chance_rate", "p_chi2", "p_permutation") if c in table1]]
sig
