"""Task ``cdbn_synthesize``: head motion for a speech file under constraints (TSV rows start, end,
label), written as a BVH of the audio's duration (the seated skeleton of the semi-synthetic corpus,
or the model's training skeleton). ``task.model``: a model_*.npz written by ``cdbn_eval``; without it a
CDBN is trained on the semi-synthetic corpus (``cdbn.constrain.states_per_constraint`` states each)."""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from ..errors import CDBNError, ConfigError
from ..api import cdbn_corpus as ensure_corpus, cdbn_params as params


@dataclass(frozen=True)
class CDBNSynthesizeSettings:
    """``conf/task/cdbn_synthesize.yaml``."""

    name: str = "cdbn_synthesize"
    audio: Optional[str] = None         # WAV to animate (required)
    constraints: Optional[str] = None   # TSV rows: start end label (labels from cdbn.constraints); None: all 'other'
    model: Optional[str] = None         # a model_cdbn.npz / model_jdbn.npz; None: train a CDBN on the semi-synthetic corpus
    output: Optional[str] = None        # BVH name inside the output directory (None: <audio stem>.bvh)


def run(cfg, out_dir: Path) -> dict:
    from ..cdbn.dataset import load_semisynthetic_turns, normalize_by_subject
    from ..cdbn.experiment import fit
    from ..cdbn.features import (
        FEATURE_LAYOUT,
        Normalization,
        read_constraints,
        speech_features,
    )
    from ..cdbn.modelio import load_model
    from ..cdbn.semisynthetic import head_motion
    from ..cdbn.synthesize import head_into_motion, keypoint_smooth, synthesize_head
    from ..io.audio import load_audio
    from ..io.bvh import save_bvh

    t0 = time.perf_counter()
    from ..config import task_settings

    task = task_settings(cfg)
    if not task.audio:
        raise ConfigError("task.audio is required: convsynth task=cdbn_synthesize task.audio=F.wav")
    p = params(cfg)
    fps = p.features.fps
    audio = load_audio(task.audio)
    n = round(audio.duration * fps)
    if task.model:
        model, extra = load_model(task.model, FEATURE_LAYOUT)
        if "motion_mean" not in extra:
            raise CDBNError("model file lacks motion_mean/motion_sd (write it with task=cdbn_eval)", task.model)
        mmean, msd = extra["motion_mean"], extra["motion_sd"]
    else:
        turns, norms = normalize_by_subject(load_semisynthetic_turns(ensure_corpus(cfg, p), p.constraints, p.features))
        tm = fit("cdbn", turns, p.constrain.states_per_constraint, p)
        model = tm.model
        mmean = np.mean([v[1].mean for v in norms.values()], axis=0)
        msd = np.mean([v[1].sd for v in norms.values()], axis=0)
    t_model = time.perf_counter() - t0
    names = model.constraint_names
    codes = (read_constraints(task.constraints, names, n, fps) if task.constraints
             else np.zeros(n, np.int32))
    t1 = time.perf_counter()
    raw = speech_features(audio, p.features, n, fps, path=task.audio)
    z = Normalization.fit(raw).apply(raw)      # the input speaker's own z-normalization (Sec. IV-C)
    cons = codes if model.num_constraints > 1 else None
    angles, _gamma = synthesize_head(model, z, cons, p.synth.posterior, mmean, msd)
    q = keypoint_smooth(angles, fps, p.synth.keypoints_per_second)
    template = head_motion(np.zeros((2, 3)), fps, "template")
    motion = head_into_motion(template, q, p.features.head_joints, Path(task.audio).stem)
    name = task.output or f"{Path(task.audio).stem}.bvh"
    out = save_bvh(motion, Path(out_dir) / name)
    return {"success": True, "bvh": str(out), "frames": int(n), "seconds": n / fps,
            "audio_seconds": audio.duration, "model_states": model.num_states,
            "constraint_frames": {nm: int((codes == k).sum()) for k, nm in enumerate(names)},
            "model_seconds": t_model, "synthesis_seconds": time.perf_counter() - t1}
