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
# # A converse sweep over conditions
# `task=converse` on the same speech under each ablation condition, collected with
# `convsynth task=collect task.dir=multirun/converse/<stamp>` (docs/notebooks.md). Constraints met are
# counted on the same denominator in every condition: the constraints the checker judges under
# condition `all` (every kind on); those a condition switches off are reported apart, never as met.
# Reads `converse_by_condition.csv` and `converse_by_kind.csv` of the newest collected converse sweep;
# without one, the project's stored sweep on real speech
# (`experiments/results/converse_conditions_real_speech/`).

# %% tags=["parameters"]
converse = None  # a task=collect folder of a converse sweep; None: the newest outputs/collect/* holding one, else the stored one

# %%
import sys
from pathlib import Path

sys.path.insert(0, str(Path.cwd()))
import pandas as pd
from _paths import newest, reads, show

from convsynth_jax.figures.converse import converse_conditions_figure

src = newest("collect", "converse_by_condition.csv",
             stored="converse_conditions_real_speech/converse_by_condition.csv", given=converse)
by_kind_src = src.parent / "converse_by_kind.csv"
reads(src, by_kind_src)
table = pd.read_csv(src)
table[["condition", "speaker", "character", "constraints", "met", "share_met", "switched_off", "kinds_off",
       "share_met_on"]]

# %%
show(converse_conditions_figure(table))

# %% [markdown]
# By constraint kind (`on`: the condition asks for the kind; `constraints`: condition all's count).

# %%
by_kind = pd.read_csv(by_kind_src)
by_kind.pivot_table(index=["speaker", "kind"], columns="condition", values="met", aggfunc="first", sort=False)
