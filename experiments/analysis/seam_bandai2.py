"""Seams on real motion capture (Bandai-Namco 2, ``../shared/data/bandai2/bvh``; 21 joints, no finger
joints: the hands end at Hand_L / Hand_R), with and without the seam filter (graph/seams.py).

    python experiments/analysis/seam_bandai2.py [--root DIR] [--pattern GLOB] [--quantiles 0.98 ...] [--sample N]

For each setting the graph is built with the default construction (k = 3, Johnson SB threshold,
22.25% key states), then ``--sample`` of its synthetic transitions i -> j (seeded) are realized as
a 2 s path (1 s of the source clip up to i, 1 s of the target clip from j, 12-frame cosine blend)
and scored like leave-one-out's ``seam_ratio``: the largest root-relative acceleration within 3
frames of the transition over the largest of a "ground-truth" window of the same length drawn from
a third clip (seeded). Reported: edges before/after the filter, states after the SCC, and the share
of sampled transitions with a ratio over 1, the median and the 95th percentile. Writes
``experiments/results/seam_bandai2.{json,md}``.
"""
import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))

from convsynth_jax.evaluation import metrics  # noqa: E402
from convsynth_jax.graph import build_database, build_graph  # noqa: E402
from convsynth_jax.graph.database import bvh_folder_clips  # noqa: E402
from convsynth_jax.graph.params import GraphParams  # noqa: E402
from convsynth_jax.kinematics import forward_kinematics  # noqa: E402
from convsynth_jax.synth.realize import realize  # noqa: E402

HALF = 30  # frames either side of the transition


def rr_acc(motion) -> np.ndarray:
    return metrics.root_relative_acceleration(np.asarray(forward_kinematics(motion), np.float64), motion.fps)


def score(g, motions, rng, n_sample):
    ef = g.edges_frame()
    syn = ef[ef["synthetic"]]
    names = list(motions)
    ok = [(r.source_file, int(r.source_frame), r.target_file, int(r.target_frame)) for r in syn.itertuples()
          if r.source_frame >= HALF - 1 and r.source_frame + 13 < motions[r.source_file].num_frames
          and r.target_frame + HALF <= motions[r.target_file].num_frames]
    pick = [ok[k] for k in rng.choice(len(ok), min(n_sample, len(ok)), replace=False)]
    ratios = []
    for sc, sf, tc, tf in pick:
        clips = [sc] * HALF + [tc] * HALF
        frames = list(range(sf - HALF + 1, sf + 1)) + list(range(tf, tf + HALF))
        m = realize(clips, frames, motions, [HALF], blend_frames=12)
        acc = rr_acc(m)
        peak = acc[HALF - 1 - 3: HALF - 1 + 4].max()  # rows u - 1 for output frames u = HALF - 3 .. HALF + 3
        while True:  # a ground-truth window of a third clip, long enough
            gc = names[int(rng.integers(len(names)))]
            if gc not in (sc, tc) and motions[gc].num_frames >= 2 * HALF:
                break
        g0 = int(rng.integers(motions[gc].num_frames - 2 * HALF + 1))
        ratios.append(peak / rr_acc(motions[gc].slice(g0, g0 + 2 * HALF)).max())
    return np.array(ratios), len(ok)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--root", default=str(REPO.parent / "shared" / "data" / "bandai2" / "bvh"))
    ap.add_argument("--pattern", default="*.bvh")
    ap.add_argument("--quantiles", type=float, nargs="*", default=[0.98, 0.95])
    ap.add_argument("--sample", type=int, default=400)
    ap.add_argument("--out", default=str(REPO / "experiments" / "results" / "seam_bandai2"))
    args = ap.parse_args()
    t0 = time.perf_counter()
    clips = bvh_folder_clips(args.root, args.pattern)
    motions = {n: m for n, m, _, _ in clips}
    db = build_database(clips)
    print(f"{len(clips)} clips, {db.num_frames} frames, joints {len(db.joint_names)} "
          f"(finger joints: {sum(w == 0 for w in db.weights)}); loaded in {time.perf_counter() - t0:.1f} s", flush=True)
    rows = []
    for q in [None, *args.quantiles]:
        g = build_graph(db, GraphParams(seam_filter_quantile=q))
        r, n_ok = score(g, motions, np.random.default_rng(0), args.sample)
        sf = g.meta["kernel"].get("seam_filter", {})
        rows.append({"seam_filter_quantile": q, "acceleration_limit": sf.get("acceleration_limit"),
                     "dropped": sf.get("dropped", 0), "candidates": sf.get("candidates", g.meta["num_synthetic_before_scc"]),
                     "states_after_scc": g.num_states, "states": g.meta["num_states_before_scc"],
                     "synthetic_after_scc": g.meta["num_synthetic_edges"], "sampled": int(r.size),
                     "over_1": float((r > 1).mean()), "median": float(np.median(r)), "p95": float(np.quantile(r, 0.95))})
        print(rows[-1], flush=True)
    lines = [f"Bandai-Namco 2 ({len(clips)} clips `{args.pattern}`, {db.num_frames} frames, no finger joints); "
             f"{args.sample} sampled transitions per graph, 2 s paths, ground truth a 2 s window of a third clip.", "",
             "| seam_filter_quantile | limit | dropped / candidates | states after SCC | synthetic after SCC | "
             "share > 1 | median | 95th pct |", "|---" * 8 + "|"]
    for r in rows:
        lim = "-" if r["acceleration_limit"] is None else f"{r['acceleration_limit']:.0f}"
        lines.append(f"| {r['seam_filter_quantile']} | {lim} | {r['dropped']} / {r['candidates']} | "
                     f"{r['states_after_scc']} / {r['states']} | {r['synthetic_after_scc']} | {100 * r['over_1']:.1f}% | "
                     f"{r['median']:.2f} | {r['p95']:.2f} |")
    Path(args.out + ".md").write_text("\n".join(lines) + "\n")
    Path(args.out + ".json").write_text(json.dumps({"pattern": args.pattern, "clips": len(clips), "rows": rows,
                                                    "seconds": time.perf_counter() - t0}, indent=2))
    print("\n".join(lines))
