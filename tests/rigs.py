"""Tiny skeletons and GENEA-layout dyadic corpora in the joint names and hierarchies of common rigs.

Each rig is written as an indented tree (two spaces a level; "*" marks an End Site under a joint),
upper body complete, legs and fingers abridged. Names come from the rigs' own files: SMPL-X's joint
list, the CMU mocap BVH conversion, Mixamo FBX exports, GENEA 2022/2023 (Talking With Hands), BEAT and
Bandai-Namco-Research-Motiondataset (same tree as tests/data/*.bvh).
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd

from convsynth_jax.io import save_bvh
from convsynth_jax.io.audio import save_wav
from convsynth_jax.io.transcripts import save_transcript_tsv
from convsynth_jax.skeleton import Motion, Skeleton

RIG_TREES = {
    "smplx": """
pelvis
  left_hip
    left_knee
      left_ankle
        left_foot
  right_hip
    right_knee
      right_ankle
        right_foot
  spine1
    spine2
      spine3
        neck
          head
            jaw
            left_eye_smplhf
            right_eye_smplhf
        left_collar
          left_shoulder
            left_elbow
              left_wrist
                left_index1
                  left_index2
                left_thumb1
                  left_thumb2
        right_collar
          right_shoulder
            right_elbow
              right_wrist
                right_index1
                  right_index2
                right_thumb1
                  right_thumb2
""",
    "cmu": """
Hips
  LHipJoint
    LeftUpLeg
      LeftLeg
        LeftFoot
          LeftToeBase *
  RHipJoint
    RightUpLeg
      RightLeg
        RightFoot
          RightToeBase *
  LowerBack
    Spine
      Spine1
        Neck
          Neck1
            Head *
        LeftShoulder
          LeftArm
            LeftForeArm
              LeftHand
                LeftFingerBase
                  LeftHandIndex1 *
                LThumb *
        RightShoulder
          RightArm
            RightForeArm
              RightHand
                RightFingerBase
                  RightHandIndex1 *
                RThumb *
""",
    "mixamo": """
mixamorig:Hips
  mixamorig:Spine
    mixamorig:Spine1
      mixamorig:Spine2
        mixamorig:Neck
          mixamorig:Head
            mixamorig:HeadTop_End *
        mixamorig:LeftShoulder
          mixamorig:LeftArm
            mixamorig:LeftForeArm
              mixamorig:LeftHand
                mixamorig:LeftHandThumb1
                  mixamorig:LeftHandThumb2 *
                mixamorig:LeftHandIndex1
                  mixamorig:LeftHandIndex2 *
        mixamorig:RightShoulder
          mixamorig:RightArm
            mixamorig:RightForeArm
              mixamorig:RightHand
                mixamorig:RightHandThumb1
                  mixamorig:RightHandThumb2 *
                mixamorig:RightHandIndex1
                  mixamorig:RightHandIndex2 *
  mixamorig:LeftUpLeg
    mixamorig:LeftLeg
      mixamorig:LeftFoot
        mixamorig:LeftToeBase
          mixamorig:LeftToe_End *
  mixamorig:RightUpLeg
    mixamorig:RightLeg
      mixamorig:RightFoot
        mixamorig:RightToeBase
          mixamorig:RightToe_End *
""",
    "genea": """
body_world
  b_root
    b_l_upleg
      b_l_leg
        b_l_foot_twist
          b_l_foot *
    b_r_upleg
      b_r_leg
        b_r_foot_twist
          b_r_foot *
    b_spine0
      b_spine1
        b_spine2
          b_spine3
            b_neck0
              b_head
                b_head_null *
                b_jaw *
                b_l_eye *
                b_r_eye *
            b_l_shoulder
              p_l_scap *
              b_l_arm
                b_l_arm_twist *
                b_l_forearm
                  b_l_wrist_twist
                    b_l_wrist
                      b_l_thumb0
                        b_l_thumb1 *
                      b_l_index1 *
            b_r_shoulder
              p_r_scap *
              b_r_arm
                b_r_arm_twist *
                b_r_forearm
                  b_r_wrist_twist
                    b_r_wrist
                      b_r_thumb0
                        b_r_thumb1 *
                      b_r_index1 *
""",
    "beat": """
Hips
  Spine
    Spine1
      Spine2
        Spine3
          Neck
            Neck1
              Head
                HeadEnd *
          LeftShoulder
            LeftArm
              LeftForeArm
                LeftHand
                  LeftHandThumb1
                    LeftHandThumb2 *
                  LeftHandIndex1
                    LeftHandIndex2 *
                  LeftHandMiddle1 *
          RightShoulder
            RightArm
              RightForeArm
                RightHand
                  RightHandThumb1
                    RightHandThumb2 *
                  RightHandIndex1
                    RightHandIndex2 *
                  RightHandMiddle1 *
  LeftUpLeg
    LeftLeg
      LeftFoot
        LeftForeFoot
          LeftToeBase *
  RightUpLeg
    RightLeg
      RightFoot
        RightForeFoot
          RightToeBase *
""",
    "bandai": """
joint_Root
  Hips
    Spine
      Chest
        Neck
          Head *
        Shoulder_L
          UpperArm_L
            LowerArm_L
              Hand_L *
        Shoulder_R
          UpperArm_R
            LowerArm_R
              Hand_R *
    UpperLeg_L
      LowerLeg_L
        Foot_L
          Toes_L *
    UpperLeg_R
      LowerLeg_R
        Foot_R
          Toes_R *
""",
}

# role -> joint each rig's defaults must choose (the shoulder role is the upper arm)
EXPECTED = {
    "smplx": ("left_wrist", "left_shoulder", "right_wrist", "right_shoulder", "neck", "head"),
    "cmu": ("LeftHand", "LeftArm", "RightHand", "RightArm", "Neck", "Head"),
    "mixamo": ("mixamorig:LeftHand", "mixamorig:LeftArm", "mixamorig:RightHand", "mixamorig:RightArm",
               "mixamorig:Neck", "mixamorig:Head"),
    "genea": ("b_l_wrist", "b_l_arm", "b_r_wrist", "b_r_arm", "b_neck0", "b_head"),
    "beat": ("LeftHand", "LeftArm", "RightHand", "RightArm", "Neck", "Head"),
    "bandai": ("Hand_L", "UpperArm_L", "Hand_R", "UpperArm_R", "Neck", "Head"),
}

_LEFT = re.compile(r"left|(^|_)l_|_L$|^L[A-Z]|(^|:)Left")
_RIGHT = re.compile(r"right|(^|_)r_|_R$|^R[A-Z]|(^|:)Right")
_LEG = re.compile(r"leg|hip|knee|ankle|foot|toe", re.IGNORECASE)


def rig_skeleton(rig: str) -> Skeleton:
    """The rig's tree as a Skeleton: offsets 8 units up the spine, sideways along the arms, down the
    legs; the root carries position channels."""
    names, parents, offsets, ends, stack = [], [], [], [], []
    for line in RIG_TREES[rig].strip("\n").splitlines():
        depth = (len(line) - len(line.lstrip())) // 2
        name, _, star = line.strip().partition(" ")
        del stack[depth:]
        side = 1.0 if _LEFT.search(name) and not _LEG.search(name) else -1.0 if _RIGHT.search(name) \
            and not _LEG.search(name) else 0.0
        down = -1.0 if _LEG.search(name) else 1.0
        off = (8.0 * side, 0.0 if side else 8.0 * down, 0.0) if stack else (0.0, 0.0, 0.0)
        names.append(name)
        parents.append(stack[-1] if stack else -1)
        offsets.append(off)
        if star:
            ends.append((len(names) - 1, (0.0, 6.0, 0.0)))
        stack.append(len(names) - 1)
    rot = ("Zrotation", "Xrotation", "Yrotation")
    channels = tuple((("Xposition", "Yposition", "Zposition") + rot) if p < 0 else rot for p in parents)
    return Skeleton(tuple(names), tuple(parents), np.asarray(offsets, float), channels, tuple(ends))


def rig_motion(rig: str, seconds: float, seed: int, fps: float = 30.0) -> Motion:
    """Every joint swinging on a slow sinusoid with a random phase, plus an arm and head burst."""
    skel = rig_skeleton(rig)
    rng = np.random.default_rng(seed)
    n, J = int(round(seconds * fps)), skel.num_joints
    t = np.arange(n) / fps
    angle = 0.05 * np.sin(2 * np.pi * 0.3 * t[:, None] + rng.uniform(0, 2 * np.pi, J))
    burst = np.exp(-0.5 * ((t - seconds * rng.uniform(0.3, 0.7)) / 0.25) ** 2)
    angle = angle + 0.8 * burst[:, None] * rng.uniform(-1, 1, J)
    axis = rng.normal(size=(J, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    q = np.concatenate([np.cos(angle / 2)[..., None], np.sin(angle / 2)[..., None] * axis], axis=-1)
    trans = np.broadcast_to(skel.offsets, (n, J, 3)).copy()
    trans[:, 0] = [0.0, 90.0, 0.0]
    return Motion(skel, q, trans, fps, name=rig)


WORDS = {
    "main-agent": [(0.3, 0.6, "so"), (0.6, 0.8, "I"), (0.8, 1.1, "like"), (1.1, 1.3, "to"), (1.3, 1.7, "walk"),
                   (2.4, 2.7, "um"), (3.3, 3.7, "really"), (3.7, 4.2, "far")],
    "interloctr": [(1.9, 2.2, "yeah"), (2.9, 3.2, "okay"), (4.6, 5.0, "right")],
}


def _speech(words, seconds: float, rate: int = 16000) -> np.ndarray:
    """Harmonic tones with a falling pitch during each word, faint noise elsewhere."""
    t = np.arange(int(seconds * rate)) / rate
    x = 0.001 * np.random.default_rng(0).normal(size=t.size)
    for s, e, _ in words:
        m = (t >= s) & (t < e)
        f0 = 180 - 40 * (t[m] - s) / (e - s)
        phase = 2 * np.pi * np.cumsum(f0) / rate
        x[m] += 0.3 * sum(np.sin(k * phase) / k for k in (1, 2, 3)) * np.hanning(m.sum())
    return x


def write_rig_corpus(root: Path, rig: str, sessions=("s01", "s02"), seconds: float = 5.5) -> Path:
    """A GENEA dyadic folder: per session <session>_main-agent.{bvh,wav,tsv} and _interloctr."""
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    for k, session in enumerate(sessions):
        for r, role in enumerate(("main-agent", "interloctr")):
            stem = root / f"{session}_{role}"
            save_bvh(rig_motion(rig, seconds, seed=10 * k + r), stem.with_suffix(".bvh"))
            save_wav(stem.with_suffix(".wav"), _speech(WORDS[role], seconds), 16000)
            save_transcript_tsv(pd.DataFrame(WORDS[role], columns=["start", "end", "word"]), stem.with_suffix(".tsv"))
    return root
