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
# # Corpus overview
# Sessions, durations, transcripts and planted events of the dyadic corpus used by the last main run,
# and the joint-speed curves the motion segmentation works on.

# %% tags=["parameters"]
run = None  # a main run folder; None: the newest outputs/main/* of the checkout

# %%
import sys
from pathlib import Path

sys.path.insert(0, str(Path.cwd()))
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from _paths import corpus_dir, reads, show

from convsynth_jax.kinematics import forward_kinematics
from convsynth_jax.io import load_corpus

root = corpus_dir(run)  # the run's summary.json names it
reads(root)
corpus = load_corpus(root)
rows = []
for s in corpus.sessions:
    for p in s.participants:
        words = p.load_transcript()
        m = p.load_motion()
        rows.append({"session": s.name, "role": p.role, "character": p.character, "frames": m.num_frames,
                     "seconds": m.num_frames / m.fps, "words": len(words)})
overview = pd.DataFrame(rows)
overview

# %%
print(overview.groupby("character")[["seconds", "words"]].sum())

# %%
events_file = Path(corpus.root) / "events.csv"
if events_file.exists():
    events = pd.read_csv(events_file)
    print(events.groupby(["participant", "kind"]).size().unstack(fill_value=0))

# %%
p = corpus.sessions[0].participants[0]
m = p.load_motion()
pos = np.asarray(forward_kinematics(m))
speed = np.linalg.norm(np.diff(pos, axis=0), axis=-1) * m.fps
fig, ax = plt.subplots(figsize=(8, 3))
for name in ("LeftHand", "RightHand", "Head"):
    if name in m.skeleton.names:
        ax.plot(np.arange(len(speed)) / m.fps, speed[:, m.skeleton.index(name)], label=name, lw=0.8)
ax.set_xlabel("time (s)"); ax.set_ylabel("speed (cm/s)"); ax.legend()
fig.tight_layout()
show(fig)
