"""Check that two saved motion graphs (``graph.npz`` of ``convsynth task=build_graph``) are identical:
every state and edge array bit for bit (edges, costs, synthetic flags, clips, frames, audio) and the
threshold and w_v. Used to check that a speed-up of the construction does not change the graph:

    python experiments/analysis/compare_graphs.py OLD/graph.npz NEW/graph.npz

Prints one line per array and exits with status 1 on any difference.
"""
import sys

import numpy as np

from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
from _bench import REPO  # noqa: F401  (puts the repository on the path)
from convsynth_jax.graph import load_graph


def main(a_path, b_path) -> int:
    a, b = load_graph(a_path), load_graph(b_path)
    bad = 0
    for name in a._ARRAYS:
        x, y = np.asarray(getattr(a, name)), np.asarray(getattr(b, name))
        same = x.shape == y.shape and x.dtype == y.dtype and np.array_equal(x, y)
        bad += not same
        print(f"{name:16s} {str(x.shape):14s} {'identical' if same else 'DIFFERENT'}")
    for key in ("threshold", "w_v", "num_states", "num_edges", "num_synthetic_edges"):
        same = a.meta.get(key) == b.meta.get(key)
        bad += not same
        print(f"meta {key:11s} {a.meta.get(key)!s:>14s} {'identical' if same else 'DIFFERENT: ' + str(b.meta.get(key))}")
    print("graphs identical" if not bad else f"{bad} differences")
    return int(bad > 0)


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:3]))
