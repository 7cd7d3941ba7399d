"""Nested blends on real motion capture (issue #15 part 2): random paths over Bandai-Namco 2
gesture clips (wave and raise, the 'normal' style) with runs of 1, 2, 3, 15 or 30 frames between
synthetic transitions, so that many transitions fall inside an ongoing blend; realized with
``synth.realize`` (12-frame cosine blends). Figure: the largest root-relative acceleration within 3
frames of a transition over the largest of the source clips, per path. The transitions are random
(no cost threshold, unlike a motion graph's), so values over 1 are expected; the point is the
comparison with another realization, given as a previous ``realize.py`` (e.g. from ``git show
96a0e09:convsynth_jax/synth/realize.py > /tmp/old_realize.py``). Writes
experiments/results/seam_nested_real.json.

    python experiments/seam_nested_real.py [--old /tmp/old_realize.py] [--paths 40]
"""
import argparse
import importlib.util
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

from _bench import SHARED, write  # noqa: E402

from convsynth_jax.evaluation import metrics  # noqa: E402
from convsynth_jax.io.bvh import load_bvh  # noqa: E402
from convsynth_jax.kinematics import forward_kinematics  # noqa: E402
from convsynth_jax.synth.realize import realize  # noqa: E402


def acc(m):
    return metrics.root_relative_acceleration(np.asarray(forward_kinematics(m), np.float64), m.fps)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--old", default=None, help="a previous realize.py to compare with")
    ap.add_argument("--paths", type=int, default=40)
    args = ap.parse_args()
    bvh = Path(SHARED) / "bandai2" / "bvh"
    files = sorted(bvh.glob("*wave*normal*.bvh"))[:6] + sorted(bvh.glob("*raise*normal*.bvh"))[:6]
    if not files:
        raise SystemExit(f"no Bandai-Namco 2 clips under {bvh}")
    motions = {str(f): load_bvh(f) for f in files}
    names = list(motions)
    src_max = max(float(acc(m).max()) for m in motions.values())
    variants = {"nested": realize}
    if args.old:
        spec = importlib.util.spec_from_file_location("convsynth_jax.synth._old_realize", args.old)
        old = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(old)
        variants["old"] = old.realize
    rng = np.random.default_rng(0)
    res = {k: [] for k in variants}
    for _ in range(args.paths):
        clips, frames, syn, t, c, f = [], [], [], 0, rng.choice(names), 0
        while t < 150:
            for _ in range(int(rng.choice([1, 2, 3, 15, 30]))):
                if t >= 150:
                    break
                clips.append(c); frames.append(min(f, motions[c].num_frames - 1)); f += 1; t += 1
            if t < 150:
                syn.append(t); c = rng.choice(names); f = int(rng.integers(0, motions[c].num_frames - 40))
        for name, fn in variants.items():
            a = acc(fn(clips, frames, motions, syn, blend_frames=12))
            rows = sorted({u - 1 for s in syn for u in range(s - 3, s + 4) if 0 <= u - 1 < a.shape[0]})
            res[name].append(float(a[rows].max()) / src_max)
    out = {"clips": [Path(f).name for f in files], "paths": args.paths, "source_max_acceleration": src_max,
           **{k: {"median": float(np.median(v)), "max": float(np.max(v)), "over_1": int(np.sum(np.array(v) > 1))}
              for k, v in res.items()}}
    write("seam_nested_real", out)
