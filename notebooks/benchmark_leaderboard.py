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
# # Benchmark leaderboard
# Every system and the two controls scored with the field's metrics on the same leave-one-out
# windows (`convsynth task=benchmark`, docs/metrics.md): value, bootstrap 95% interval over sessions
# and rank per metric. Reads `leaderboard.csv` of a benchmark run; without one, the project's stored
# leaderboard (`experiments/results/bench_metrics_leaderboard.csv`, all 17 folds of the default corpus).

# %% tags=["parameters"]
benchmark = None  # a task=benchmark output folder; None: the newest outputs/benchmark/*, else the stored leaderboard

# %%
import sys
from pathlib import Path

sys.path.insert(0, str(Path.cwd()))
import pandas as pd
from _paths import newest, reads, show

from convsynth_jax.figures.benchmark import leaderboard_figure

src = newest("benchmark", "leaderboard.csv", stored="bench_metrics_leaderboard.csv", given=benchmark)
reads(src)
board = pd.read_csv(src)
board.head()

# %% [markdown]
# One row per system and scope, one column per metric: value (rank).

# %%
wide = board.assign(cell=[f"{v:.4g} ({r:g})" for v, r in zip(board["value"], board["rank"])]).pivot_table(
    index=["scope", "system"], columns="metric", values="cell", aggfunc="first")
wide

# %%
for scope, g in board.groupby("scope"):
    print(scope)
    show(leaderboard_figure(g))
