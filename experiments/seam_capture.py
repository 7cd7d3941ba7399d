"""Diagnostic: run leave-one-out windows once and keep each solved window's path (source clip and
frame per output frame, the synthetic transitions, the chair), so that realization variants can be
re-scored on the same paths without searching again (``experiments/seam_diagnose.py``).

    python experiments/seam_capture.py --cache DIR --folds 0 1 2 3 --out FILE.pkl [overrides ...]

The realization does not feed back into the search, so a window's seam depends only on its path and
on ``realize``; the paths written here are those ``bench_loo.py`` would realize with the same
configuration (same seeds, ``derive_seed``).
"""
import argparse
import pickle
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

from convsynth_jax.config import default_params  # noqa: E402
from convsynth_jax.evaluation import loo  # noqa: E402
from convsynth_jax.synth import pipeline  # noqa: E402
from convsynth_jax.systems.base import make_system  # noqa: E402
from convsynth_jax.tasks.common import annotated_corpus, cache_dir  # noqa: E402

if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--cache", required=True)
    ap.add_argument("--folds", type=int, nargs="+", required=True)
    ap.add_argument("--conditions", nargs="*", default=None)
    ap.add_argument("--out", required=True)
    ap.add_argument("overrides", nargs="*")
    args = ap.parse_args()
    params = default_params([f"cache_dir={args.cache}", "progress=false", *args.overrides])
    system = make_system(params, params.system)
    corpus, ann = annotated_corpus(params)
    cache = cache_dir(params)
    captured, last = [], {}
    real_realize, real_eval = pipeline.realize, loo.evaluate_window

    def spy_realize(clips, frames, motions, syn_at, **kw):
        last.update(clips=list(clips), frames=[int(f) for f in frames], synthetic_at=[int(t) for t in syn_at], **kw)
        return real_realize(clips, frames, motions, syn_at, **kw)

    state = {}

    def spy_eval(system_, model, win, condition, gt_motion, clip_audio, params_, **kw):
        last.clear()
        row, motion = real_eval(system_, model, win, condition, gt_motion, clip_audio, params_, **kw)
        if motion is not None and last:
            captured.append({"fold": state["fold"], "condition": condition, "session": win.session, "role": win.role,
                             "start_frame": int(win.start_frame), "character": win.character, "seed": int(win.seed),
                             "num_frames": int(win.num_frames), "seam_ratio": row.get("seam_ratio"),
                             "jerk": row.get("jerk"), "max_jump": row.get("max_jump"), **last})
        return row, motion

    pipeline.realize, loo.evaluate_window = spy_realize, spy_eval
    conds = args.conditions or list(system.conditions)
    t0 = time.perf_counter()
    for fold in args.folds:
        state["fold"] = fold
        models: dict = {}
        for cond in conds:
            tf = time.perf_counter()
            loo.run_fold(system, ann, fold, cond, params, cache_dir=cache, models=models,
                         with_audio=system.needs_audio)
            print(f"fold {fold} {cond}: {time.perf_counter() - tf:.1f} s, {len(captured)} windows so far", flush=True)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    with open(args.out, "wb") as fh:
        pickle.dump({"overrides": args.overrides, "windows": captured}, fh)
    print(f"{len(captured)} solved windows in {time.perf_counter() - t0:.0f} s -> {args.out}")
