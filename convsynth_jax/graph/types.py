"""The MotionGraph container shared by construction (graph/), search (search/) and realization (synth/).

States are frames of the database (a subset after pruning), edges are kept in CSR form.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import GraphError
from ..utils import atomic_path


@dataclass(frozen=True)
class MotionGraph:
    """A motion graph over database frames.

    States (S of them, numbered 0..S-1 after pruning):
      clip: (S,) int32 index into ``clip_names``; frame: (S,) int32 frame in that clip at ``fps``;
      own_label, own_start, own_end, own_peak: (S,) audio status of the character's own channel
        (codes and clip-frame indices as in :class:`convsynth_jax.annotate.FrameAudio`);
      partner_label, partner_start, partner_end: (S,) the partner channel's status;
      is_key: (S,) bool, the state was a key state.
    Edges (E of them, CSR sorted by source): indptr (S+1,), indices (E,) target state,
      cost (E,) float32 transition cost (0 for original transitions), synthetic (E,) bool.
    meta: JSON-serializable dict (threshold, w_v, joint weights, k, quantile, distribution, ...).
    """

    clip_names: tuple[str, ...]
    fps: float
    clip: np.ndarray
    frame: np.ndarray
    own_label: np.ndarray
    own_start: np.ndarray
    own_end: np.ndarray
    own_peak: np.ndarray
    partner_label: np.ndarray
    partner_start: np.ndarray
    partner_end: np.ndarray
    is_key: np.ndarray
    indptr: np.ndarray
    indices: np.ndarray
    cost: np.ndarray
    synthetic: np.ndarray
    meta: dict = field(default_factory=dict)

    _ARRAYS = ("clip", "frame", "own_label", "own_start", "own_end", "own_peak", "partner_label",
               "partner_start", "partner_end", "is_key", "indptr", "indices", "cost", "synthetic")

    @property
    def num_states(self) -> int:
        return int(self.clip.shape[0])

    @property
    def num_edges(self) -> int:
        return int(self.indices.shape[0])

    def out_edges(self, s: int):
        """(targets, costs, synthetic flags) of state s."""
        a, b = int(self.indptr[s]), int(self.indptr[s + 1])
        return self.indices[a:b], self.cost[a:b], self.synthetic[a:b]

    def edges_frame(self):
        """One row per edge: source_file, source_frame, target_file, target_frame, cost, synthetic."""
        import pandas as pd

        src = np.repeat(np.arange(self.num_states), np.diff(self.indptr))
        names = np.asarray(self.clip_names, dtype=object)
        return pd.DataFrame({
            "source_file": names[self.clip[src]],
            "source_frame": self.frame[src].astype(np.int64),
            "target_file": names[self.clip[self.indices]],
            "target_frame": self.frame[self.indices].astype(np.int64),
            "cost": self.cost.astype(np.float64),
            "synthetic": self.synthetic.astype(bool),
        })

    def save(self, path: str | Path) -> Path:
        """Compressed .npz with the arrays plus JSON metadata; written atomically."""
        path = Path(path)
        payload = {k: np.asarray(getattr(self, k)) for k in self._ARRAYS}
        payload["clip_names"] = np.asarray(self.clip_names, dtype=str)
        payload["fps"] = np.asarray(self.fps)
        payload["meta_json"] = np.asarray(json.dumps(self.meta, default=float))
        with atomic_path(path, suffix=".npz") as tmp:
            with open(tmp, "wb") as fh:
                np.savez_compressed(fh, **payload)
        return path


def load_graph(path: str | Path) -> MotionGraph:
    path = Path(path)
    if not path.is_file():
        from ..errors import MissingFileError

        raise MissingFileError("motion graph file not found", path)
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in MotionGraph._ARRAYS}
            names = tuple(str(s) for s in z["clip_names"])
            fps = float(z["fps"])
            meta = json.loads(str(z["meta_json"]))
    except (KeyError, ValueError, OSError) as e:
        raise GraphError(f"not a motion graph file ({e})", path) from None
    return MotionGraph(names, fps, meta=meta, **arrays)
