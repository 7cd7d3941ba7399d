"""A conversation from two real speech recordings with the flow-matching system, no transcript read:
what ``task=converse`` does for ``system=flow_matching`` (the conversation task chains motion-graph
paths; this script makes the same calls the system offers for any length: models fitted on every
session of the corpus as ``task=converse`` fits them, then ``synthesize_audio`` with each speaker's
audio and the other's as the partner's, one BVH per speaker as long as the longer recording).

    nice -n 10 python experiments/analysis/flow_converse.py [--a WAV] [--b WAV] [--out DIR]

Writes DIR/A.bvh, DIR/B.bvh, DIR/report.json and experiments/results/flow_converse.json (manifest).
"""
import argparse
import time
from pathlib import Path


import numpy as np

from convsynth_jax.config import default_params
from convsynth_jax.evaluation.loo import fit_fold
from convsynth_jax.io import load_audio, load_bvh, save_bvh
from convsynth_jax.io.audio import Audio
from convsynth_jax.seeding import derive_seed
from convsynth_jax.systems.base import make_system
from convsynth_jax.utils import write_json_atomic
from convsynth_jax.api import annotated_corpus, cache_dir, SHARED_DATA, write_result


def padded(a: Audio, seconds: float) -> Audio:
    x = np.asarray(a.samples, np.float32)
    x = x.mean(axis=1) if x.ndim > 1 else x
    n = int(round(seconds * a.sample_rate))
    return Audio(np.concatenate([x, np.zeros(max(0, n - len(x)), np.float32)])[:n], a.sample_rate, a.path)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--a", default=str(SHARED_DATA / "speech" / "acoustic_corpus.wav"))
    ap.add_argument("--b", default=str(SHARED_DATA / "speech" / "cold_corpus.wav"))
    ap.add_argument("--out", default="/tmp/flow_converse")
    ap.add_argument("--override", nargs="*", default=[])
    args = ap.parse_args()
    t0 = time.perf_counter()
    params = default_params(["system=flow_matching", *args.override])
    system = make_system(params, params.system)
    _, ann = annotated_corpus(params)
    first = ann[next(iter(ann))]
    chars = [a.character for a in first.values()][:2]
    A, B = load_audio(args.a), load_audio(args.b)
    duration = max(A.duration, B.duration)
    A, B = padded(A, duration), padded(B, duration)
    fps = params.fps
    T = int(round(duration * fps))
    t1 = time.perf_counter()
    models = fit_fold(system, ann, None, "audio", cache_dir(params))    # every session, as task=converse
    fit_s = time.perf_counter() - t1
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    report = {"inputs": {"A": args.a, "B": args.b, "duration_s": duration, "num_frames": T, "fps": fps,
                         "transcript": None}, "characters": {}, "fit_seconds": fit_s}
    for k, (who, own, other) in enumerate([("A", A, B), ("B", B, A)]):
        t2 = time.perf_counter()
        seed = derive_seed(params.seed, fold=0, condition="audio", session="converse", window_frame=0, role_index=k)
        motion = system.synthesize_audio(models[chars[k]], own, other, T, fps, seed, chair_index=k,
                                         name=f"flow_matching:converse:{who}")
        path = save_bvh(motion, out / f"{who}.bvh")
        back = load_bvh(out / f"{who}.bvh")
        report["characters"][who] = {"character": chars[k], "frames": back.num_frames,
                                     "seconds_of_motion": back.num_frames / back.fps,
                                     "synthesis_seconds": time.perf_counter() - t2, "bvh": str(path)}
    report["success"] = all(v["frames"] == T for v in report["characters"].values())
    report["total_seconds"] = time.perf_counter() - t0
    write_json_atomic(out / "report.json", report)
    write_result("flow_converse", report)


if __name__ == "__main__":
    main()
