"""Benchmark: load and forward kinematics of all 54,067 frames of ../shared/data/bandai2 (465 BVH).
Goal: under 3 s wall once warm. Writes experiments/results/bench_io.json.

    python experiments/bench/bench_io.py
"""

import numpy as np

from convsynth_jax.kinematics import batched_pose_features
from convsynth_jax.io import load_bvh
from convsynth_jax.api import SHARED_DATA, timed, write_result

if __name__ == "__main__":
    files = sorted((SHARED_DATA / "bandai2" / "bvh").glob("*.bvh"))
    if not files:
        raise SystemExit(f"no BVH files under {SHARED_DATA / 'bandai2' / 'bvh'}")
    runs = []
    for rep in range(3):  # the first run includes JIT compilation
        motions, t_load = timed(lambda: [load_bvh(f) for f in files])
        (P, V), t_fk = timed(batched_pose_features, motions)
        runs.append({"load_s": t_load, "fk_features_s": t_fk, "total_s": t_load + t_fk})
    frames = sum(m.num_frames for m in motions)
    warm = runs[1:]
    write_result("bench_io", {"files": len(files), "frames": frames, "runs": runs,
                       "warm_total_s_median": float(np.median([r["total_s"] for r in warm])), "goal_s": 3.0})
