"""Benchmark: motion-graph construction on all of ../shared/data/bandai2 (54,067 frames).

Reports (load excluded): the whole construction (features, key states, threshold fit, edges, SCC)
with the JAX builder, warm; the same with the NumPy reference edge kernel, in the same run; without
key-state pruning (every frame a candidate); scaling at 1/4, 1/2, all and the data repeated 4 times;
peak memory. Goals: < 3 s, >= 15x faster than the reference, < 2 GB.

    python experiments/bench_graph.py [--skip-reference] [--skip-full]
"""
import argparse

import numpy as np
from _bench import SHARED, peak_rss_mb, timed, write

from convsynth_jax.config import compose
from convsynth_jax.graph import build_database, build_graph
from convsynth_jax.graph.database import bvh_folder_clips
from convsynth_jax.graph.reference import build_graph_reference


def construct(clips, cfg):
    db = build_database(clips, cfg)
    return build_graph(db, cfg)


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--skip-reference", action="store_true")
    ap.add_argument("--skip-full", action="store_true")
    ap.add_argument("--memory-only", action="store_true",
                    help="only the paper-scale construction, reporting this process's peak RSS")
    ap.add_argument("--no-pruning-only", action="store_true", help="only the every-frame-a-candidate run")
    args = ap.parse_args()
    clips = bvh_folder_clips(SHARED / "bandai2" / "bvh")
    cfg = compose(["corpus=bvh_folder", f"corpus.root={SHARED / 'bandai2' / 'bvh'}"])
    res = {"frames": sum(c[1].num_frames for c in clips)}
    if args.memory_only or args.no_pruning_only:
        name = "bench_graph_memory" if args.memory_only else "bench_graph_no_pruning"
        c = cfg if args.memory_only else compose(["corpus=bvh_folder", "graph.key_fraction=1.0"])
        gg, t = timed(construct, clips, c)
        write(name, {"frames": res["frames"], "seconds_including_compile": t, "num_key_states": gg.meta["num_key_states"],
                     "num_edges_before_scc": gg.meta["num_edges_before_scc"], "num_states": gg.num_states,
                     "peak_rss_mb": peak_rss_mb(), "kernel": gg.meta["kernel"]})
        raise SystemExit(0)
    _, t_cold = timed(construct, clips, cfg)
    runs = [timed(construct, clips, cfg) for _ in range(3)]
    g = runs[-1][0]
    res["cold_s"] = t_cold
    res["warm_s"] = [t for _, t in runs]
    res["warm_median_s"] = float(np.median(res["warm_s"]))
    res["stage_timings"] = g.meta["timings"]
    res["graph"] = {k: g.meta[k] for k in ("num_key_states", "key_fraction", "threshold", "w_v", "num_states_before_scc",
                                          "num_edges_before_scc", "num_states", "num_edges", "kernel")}
    if not args.skip_reference:
        db = build_database(clips, cfg)
        r, t_ref = timed(build_graph_reference, db, cfg)
        res["reference_s"] = t_ref
        res["speedup_vs_reference"] = t_ref / res["warm_median_s"]
        res["reference_same_edges"] = bool(r.num_edges == g.num_edges)
    scaling = {}
    n = len(clips)
    for label, sub in (("quarter", clips[: n // 4]), ("half", clips[: n // 2]), ("all", clips),
                       ("x4", [(f"{k}/{c[0]}", *c[1:]) for k in range(4) for c in clips])):
        construct(sub, cfg)  # warm for this size
        gg, t = timed(construct, sub, cfg)
        scaling[label] = {"frames": sum(c[1].num_frames for c in sub), "seconds": t, "edges": gg.num_edges}
    res["scaling"] = scaling
    if not args.skip_full:
        full = compose(["corpus=bvh_folder", "graph.key_fraction=1.0"])
        gf, t_full = timed(construct, clips, full)
        res["no_key_state_pruning"] = {"seconds": t_full, "num_edges_before_scc": gf.meta["num_edges_before_scc"],
                                       "num_states": gf.num_states}
    res["peak_rss_mb"] = peak_rss_mb()
    res["goals"] = {"construction_s": 3.0, "speedup": 15, "peak_mb": 2048}
    write("bench_graph", res)
