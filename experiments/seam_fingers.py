"""Diagnostic: for the windows kept by ``seam_capture.py``, where each window's sharpest seam lies
(before or after its transition, on a finger joint or not), and ``seam_ratio`` with the finger
joints left out of both motions (they weigh 0 in the transition cost, Eq. 4).

    CONVSYNTH_CACHE=DIR python experiments/seam_fingers.py FILE.pkl [FILE.pkl ...]
"""
import os
import pickle
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from seam_diagnose import rr_acc, seam_rows  # noqa: E402

from convsynth_jax.config import default_params  # noqa: E402
from convsynth_jax.synth.realize import realize  # noqa: E402
from convsynth_jax.systems.motion_graph import clip_name  # noqa: E402
from convsynth_jax.tasks.common import annotated_corpus  # noqa: E402

FINGERS = ("Thumb", "Index", "Middle")

if __name__ == "__main__":
    cache = os.environ.get("CONVSYNTH_CACHE", "data_cache")
    for f in sys.argv[1:]:
        cap = pickle.load(open(f, "rb"))
        params = default_params([f"cache_dir={cache}", "progress=false", *cap["overrides"]])
        _, ann = annotated_corpus(params)
        motions = {clip_name(s, r): a.motion for s, d in ann.items() for r, a in d.items()}
        names = motions[next(iter(motions))].skeleton.names
        keep = [k for k, n in enumerate(names) if not any(x in n for x in FINGERS)]
        before = finger = bad = 0
        nofing = []
        for w in cap["windows"]:
            if not w["synthetic_at"]:
                continue
            gt = ann[w["session"]][w["role"]].motion.slice(w["start_frame"], w["start_frame"] + w["num_frames"])
            ga = rr_acc(gt)
            m = realize(w["clips"], w["frames"], motions, w["synthetic_at"], chair=w["chair"],
                        chair_yaw_deg=w["chair_yaw_deg"], blend_frames=w["blend_frames"])
            acc = rr_acc(m)
            rows = seam_rows(w["synthetic_at"], acc.shape[0])
            a = acc[rows]
            i, j = np.unravel_index(np.argmax(a), a.shape)
            nofing.append(a[:, keep].max() / ga[:, keep].max())
            if a.max() > ga.max():
                bad += 1
                u = rows[i] + 1
                t = min(w["synthetic_at"], key=lambda x: abs(x - u))
                before += u < t
                finger += any(x in names[j] for x in FINGERS)
        nofing = np.array(nofing)
        print(f"{f}: {len(nofing)} windows with transitions, {bad} over 1; peak before its transition in {before},"
              f" on a finger joint in {finger}; without finger joints in both: over 1 in {int((nofing > 1).sum())},"
              f" worst {nofing.max():.2f}")
