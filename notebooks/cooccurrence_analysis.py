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

# %% tags=["parameters"]
run = None  # a main run folder; None: the newest outputs/main/* of the checkout

# %%
import sys
from pathlib import Path

sys.path.insert(0, str(Path.cwd()))
import pandas as pd
from _paths import reads, results_dir, show

from convsynth_jax.figures.motion_graph import table1_figure

src = results_dir(run) / "table1_cooccurrence.csv"
reads(src)
table1 = pd.read_csv(src)
table1

# %%
show(table1_figure(table1))

# %%
sig = table1[["character", "hypothesis", "rate"] + [c for c in ("chance_rate", "p_chi2", "p_permutation") if c in table1]]
sig
