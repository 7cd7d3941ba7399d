"""Benchmark: motion-graph construction on all of ../shared/data/bandai2 (54,067 frames, 465 files).

Construction = build_database (FK features) + build_graph (w_v, key states, k-step costs and the
Johnson SB fit, edges, SCC); loading the BVH files is excluded. Reported:
  * the JAX builder: cold (compiles included) and warm (median of 3) wall time, stage timings;
  * the NumPy reference builder (same stages, plain float64 edge loop) in the same run, speedup;
  * peak memory of a separate process that only loads and builds once (``--memory-only``);
  * every frame a key state (no key-state pruning) in a separate process (``--no-pruning-only``):
    its candidate transitions are counted, and the graph is built with the out-degree capped at
    ``--no-pruning-degree`` (about 37% of all frame pairs pass the threshold, ~1e9 edges, which would
    not fit in memory uncapped);
  * scaling: 1/4, 1/2, all files and the files repeated 4 times (~216,000 frames).
Goals: < 3 s, >= 15x the reference, < 2 GB. Writes experiments/results/bench_graph.json and .md.

    python experiments/bench/bench_graph.py [--skip-reference] [--skip-no-pruning] [--skip-scaling]
"""
import argparse
import json
import os
import subprocess
import sys

import jax
import numpy as np

from convsynth_jax.config import compose, to_params
from convsynth_jax.graph import build_database, build_graph
from convsynth_jax.graph.database import bvh_folder_clips
from convsynth_jax.testing.graph_reference import build_graph_reference
from convsynth_jax.api import RESULTS, SHARED_DATA, peak_rss_mb, process_memory_mb, reset_peak_rss, timed, write_result

ROOT = SHARED_DATA / "bandai2" / "bvh"
GOALS = {"construction_s": 3.0, "speedup": 15, "peak_mb": 2048}


def construct(clips, cfg):
    p = to_params(cfg)
    return build_graph(build_database(clips, p.features), p.graph)


def summary(g):
    keys = ("num_frames", "num_key_states", "key_fraction", "threshold", "w_v", "num_states_before_scc",
            "num_edges_before_scc", "num_states", "num_edges", "kernel")
    return {k: g.meta[k] for k in keys}


def child(flag, *extra):
    """Run this script in a fresh process for an isolated measurement; returns its JSON result."""
    r = subprocess.run([sys.executable, __file__, flag, *extra], capture_output=True, text=True)
    if r.returncode != 0:
        return {"error": r.stderr[-2000:]}
    return json.loads(r.stdout.strip().splitlines()[-1])


def markdown(res) -> str:
    g = res["graph"]
    lines = ["# Motion-graph construction benchmark (bandai2, all files)", "",
             f"{res['frames']} frames, {res['files']} files; load average at start {res['loadavg_start']}, "
             f"at end {res.get('loadavg_end')}; {res.get('machine', '')}.", "",
             "| measure | value | goal |", "|---|---|---|",
             f"| construction, warm median of 3 | {res['warm_median_s']:.2f} s | < {GOALS['construction_s']} s |",
             f"| construction, cold (compiles) | {res['cold_s']:.2f} s | |"]
    if "reference_s" in res:
        lines.append(f"| NumPy reference builder | {res['reference_s']:.1f} s (speedup {res['speedup_vs_reference']:.1f}x, "
                     f"same edges: {res['reference_same_edges']}) | >= {GOALS['speedup']}x |")
    m = res.get("memory", {})
    if "peak_rss_mb" in m:
        lines.append(f"| peak RSS, separate process (load + one construction) | {m['peak_rss_mb']:.0f} MB "
                     f"(after loading {m['rss_after_load_mb']:.0f} MB; peak during the construction "
                     f"{m['peak_rss_during_construction_mb']:.0f} MB) | < {GOALS['peak_mb']} MB |")
    n = res.get("no_key_state_pruning", {})
    if "seconds" in n:
        lines.append(f"| every frame a key state, out-degree <= {n['max_out_degree']} | {n['seconds']:.1f} s "
                     f"({n['candidates_found']:,} candidate transitions; peak during the construction "
                     f"{n['peak_rss_during_construction_mb']:.0f} MB) | completes |")
    lines += ["", f"Graph: {g['num_key_states']} key states ({100 * g['key_fraction']:.2f}%), threshold "
              f"{g['threshold']:.2f}, w_v {g['w_v']:.4f}; before SCC {g['num_states_before_scc']} states / "
              f"{g['num_edges_before_scc']} edges, after {g['num_states']} / {g['num_edges']}. Kernel: "
              f"{g['kernel']['tiles_computed']} of {g['kernel']['tiles_computed'] + g['kernel']['tiles_skipped']} "
              f"tiles computed ({g['kernel']['pairs_evaluated'] / 1e6:.1f} M pair costs).", "",
              "Stage timings of the last warm run (s): " + ", ".join(f"{k} {v:.3f}" for k, v in res["stage_timings"].items()),
              ""]
    if "scaling" in res:
        lines += ["| data | frames | seconds (warm) | edges |", "|---|---|---|---|"]
        lines += [f"| {k} | {v['frames']} | {v['seconds']:.2f} | {v['edges']} |" for k, v in res["scaling"].items()]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--skip-reference", action="store_true")
    ap.add_argument("--skip-no-pruning", action="store_true")
    ap.add_argument("--skip-scaling", action="store_true")
    ap.add_argument("--memory-only", action="store_true", help="(child) one construction, print peak RSS")
    ap.add_argument("--no-pruning-only", action="store_true", help="(child) every frame a key state")
    ap.add_argument("--no-pruning-degree", type=int, default=32)
    args = ap.parse_args()
    base = ["corpus=bvh_folder", f"corpus.root={ROOT}", "progress=false"]
    clips = bvh_folder_clips(ROOT)
    if args.memory_only or args.no_pruning_only:
        extra = [] if args.memory_only else ["graph.key_fraction=1.0", f"graph.max_out_degree={args.no_pruning_degree}"]
        rss_loaded = process_memory_mb("VmRSS")
        reset = reset_peak_rss()
        g, t = timed(construct, clips, compose(base + extra))
        out = {"seconds_including_compile": t, "peak_rss_mb": peak_rss_mb(), "rss_after_load_mb": rss_loaded,
               "peak_rss_during_construction_mb": process_memory_mb("VmHWM") if reset else None, **summary(g),
               "candidates_found": g.meta["kernel"].get("candidates_found"), "max_out_degree": args.no_pruning_degree}
        if args.no_pruning_only:  # warm second run
            g, out["seconds"] = timed(construct, clips, compose(base + extra))
        print(json.dumps(out, default=float))
        raise SystemExit(0)

    cfg = compose(base)
    res = {"frames": sum(c[1].num_frames for c in clips), "files": len(clips), "loadavg_start": os.getloadavg(),
           "command": "python experiments/bench/bench_graph.py " + " ".join(sys.argv[1:]),
           "machine": f"{os.cpu_count()} CPU cores, JAX device {jax.devices()[0].device_kind}"}
    _, res["cold_s"] = timed(construct, clips, cfg)
    runs = [timed(construct, clips, cfg) for _ in range(3)]
    g = runs[-1][0]
    res["warm_s"] = [t for _, t in runs]
    res["warm_median_s"] = float(np.median(res["warm_s"]))
    res["stage_timings"] = g.meta["timings"]
    res["graph"] = summary(g)
    res["memory"] = child("--memory-only")
    if not args.skip_no_pruning:
        res["no_key_state_pruning"] = child("--no-pruning-only", f"--no-pruning-degree={args.no_pruning_degree}")
    if not args.skip_scaling:
        scaling = {}
        n = len(clips)
        for label, sub in (("quarter", clips[: n // 4]), ("half", clips[: n // 2]), ("all", clips),
                           ("x4", [(f"{k}/{c[0]}", *c[1:]) for k in range(4) for c in clips])):
            construct(sub, cfg)  # compile for this size bucket
            gg, t = timed(construct, sub, cfg)
            scaling[label] = {"frames": sum(c[1].num_frames for c in sub), "seconds": t, "edges": gg.num_edges,
                              "pairs_evaluated": gg.meta["kernel"]["pairs_evaluated"]}
        res["scaling"] = scaling
    if not args.skip_reference:
        db = build_database(clips, to_params(cfg).features)
        r, t_ref = timed(build_graph_reference, db, to_params(cfg).graph)
        res["reference_s"] = t_ref
        res["speedup_vs_reference"] = t_ref / res["warm_median_s"]
        fast = g.edges_frame()
        ref = r.edges_frame()
        cols = ["source_file", "source_frame", "target_file", "target_frame"]
        res["reference_same_edges"] = bool(set(map(tuple, fast[cols].values.tolist()))
                                           == set(map(tuple, ref[cols].values.tolist())))
    res["peak_rss_mb_this_process"] = peak_rss_mb()
    res["loadavg_end"] = os.getloadavg()
    res["goals"] = GOALS
    write_result("bench_graph", res)
    (RESULTS / "bench_graph.md").write_text(markdown(res))
