"""Continuity at the joins of the flow-matching sampler's windows, on the BVH a sweep exported: the
body's mean joint step (root-relative, heading-free, fingers out; cm per frame) across each join
(the first frame a window generates after its imposed prefix) against every other step of the same
windows.

    python experiments/analysis/flow_join_continuity.py [--sweep /tmp/flow_matching_sweep/flow_matching]

Writes experiments/results/flow_join_continuity.json (manifest).
"""
import argparse
from pathlib import Path


import numpy as np

from convsynth_jax.annotate.params import AnnotateParams
from convsynth_jax.evaluation.field.params import FieldMetricParams
from convsynth_jax.evaluation.field.views import motion_view
from convsynth_jax.flow.model import FlowParams
from convsynth_jax.io import load_bvh
from convsynth_jax.api import write_result


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sweep", default="/tmp/flow_matching_sweep/flow_matching")
    args = ap.parse_args()
    p = FlowParams()
    files = sorted(Path(args.sweep).glob("*/bvh/*.bvh"))
    at, other = [], []
    for f in files:
        m = load_bvh(f)
        rel = motion_view(m, "body", FieldMetricParams().joints, AnnotateParams()).relative
        step = np.linalg.norm(np.diff(rel, axis=0), axis=-1).mean(axis=1)   # step t -> t + 1
        ratio = m.fps / p.fps
        hop = p.window_frames - p.prefix_frames
        n_model = int(np.ceil(m.num_frames / ratio))
        joins = [int(round((s + p.prefix_frames) * ratio)) for s in range(hop, n_model - p.prefix_frames, hop)]
        joins = [j for j in joins if 1 <= j < len(step) + 1]
        mask = np.zeros(len(step), bool)
        for j in joins:
            mask[j - 1] = True      # the step from the last imposed frame to the first generated one
        at.append(step[mask])
        other.append(step[~mask])
    at, other = np.concatenate(at), np.concatenate(other)
    result = {"windows": len(files), "joins": int(len(at)),
              "join_step_mean": float(at.mean()), "other_step_mean": float(other.mean()),
              "join_step_p99": float(np.percentile(at, 99)), "other_step_p99": float(np.percentile(other, 99)),
              "join_step_max": float(at.max()), "other_step_max": float(other.max()),
              "joins_above_other_p99": float((at > np.percentile(other, 99)).mean()), "sweep": args.sweep}
    write_result("flow_join_continuity", result)


if __name__ == "__main__":
    main()
