"""Task ``build_graph``.

* ``convsynth task=build_graph corpus=bvh_folder corpus.root=DIR``: one graph from every BVH file
  under DIR (motion only: key states come from keyframes alone) -> ``graph.npz``.
* with a dyadic corpus (default: the synthetic one): one graph per character from all its sessions,
  with its own and partner audio status -> ``graph_<character>.npz``.

``summary.json`` holds, for the bvh_folder case, num_frames, num_key_states, threshold,
num_states_before_scc, num_edges_before_scc, num_states, num_edges, seconds (construction wall time,
loading excluded), cpu_seconds (its CPU time, all threads of the process), w_v, joint_weights,
joint_names, root_relative. For dyadic corpora the same keys are given per character under
``graphs`` and, at the top level, summed (counts, seconds) or listed per character (threshold, w_v).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path



KEYS = ("num_frames", "num_key_states", "key_fraction", "threshold", "num_states_before_scc",
        "num_edges_before_scc", "num_states", "num_edges", "num_synthetic_edges", "seconds", "cpu_seconds", "w_v",
        "distribution", "k", "quantile", "joint_weights", "joint_names", "root_relative", "remove_yaw", "timings",
        "kernel", "scc_warning")


def character_clip_sets(params):
    """{name: clips} for the configured corpus (one set for bvh_folder, one per character otherwise)."""
    if params.corpus.kind == "bvh_folder":
        from ..errors import ConfigError
        from ..graph.database import bvh_folder_clips

        if params.corpus.root is None:
            raise ConfigError("corpus=bvh_folder needs corpus.root=DIR")
        return {"": bvh_folder_clips(params.corpus.root, params.corpus.pattern, params.fps)}
    from ..evaluation.loo import characters
    from ..systems.motion_graph import clip_name
    from .common import annotated_corpus

    _, ann = annotated_corpus(params)
    return {c: [(clip_name(a.session, a.role), a.motion, a.own, a.partner)
                for d in ann.values() for a in d.values() if a.character == c] for c in characters(ann)}


def character_graph_statistics(params, ks, **options) -> list:
    """Table 2 rows and Figure 4 data (``graph.statistics.graph_statistics`` with ``options``) of each
    character's clip set (:func:`character_clip_sets`; the bvh_folder set is called "all"), for the
    key-state granularities ``ks``."""
    from ..graph import build_database
    from ..graph.statistics import graph_statistics

    return [graph_statistics(build_database(clips, params.features), params.graph, ks, char or "all", **options)
            for char, clips in character_clip_sets(params).items()]


@dataclass(frozen=True)
class BuildGraphSettings:
    """``conf/task/build_graph.yaml``."""

    name: str = "build_graph"


def run(cfg, out_dir: Path) -> dict:
    from ..graph import build_database, build_graph
    from .common import params_of

    params = params_of(cfg)
    sets = character_clip_sets(params)
    graphs = {}
    for char, clips in sets.items():
        t0, c0 = time.perf_counter(), time.process_time()
        g = build_graph(build_database(clips, params.features), params.graph)
        g.meta["seconds"] = time.perf_counter() - t0
        g.meta["cpu_seconds"] = time.process_time() - c0
        g.save(out_dir / (f"graph_{char}.npz" if char else "graph.npz"))
        graphs[char] = {k: g.meta.get(k) for k in KEYS}
    if list(graphs) == [""]:
        return dict(graphs[""])
    top = {k: sum(v[k] for v in graphs.values()) for k in
           ("num_frames", "num_key_states", "num_states_before_scc", "num_edges_before_scc", "num_states",
            "num_edges", "seconds", "cpu_seconds")}
    if params.corpus.kind == "beat2":
        from .common import open_corpus, pairing_note

        top.update(pairing_note(open_corpus(params)))
    top.update({"threshold": {c: v["threshold"] for c, v in graphs.items()},
                "w_v": {c: v["w_v"] for c, v in graphs.items()}, "graphs": graphs})
    return top
