"""Body parts of the paper's splicing (Sec. 4.3): lower body, torso, left arm, right arm.

Joints are found by name through the project's one table of rig patterns,
:data:`convsynth_jax.rig.RIG_JOINTS` (SMPL/SMPL-X, CMU, Mixamo, GENEA, BEAT, Bandai, Unreal,
Biped); :data:`ROLES` maps this module's short role names onto it. An arm is the subtree
under its clavicle, the lower body the root chain above the spine plus both leg subtrees, the
torso everything else (spine, chest, neck, head).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import WalkTalkError
from ..rig import find_role
from ..skeleton import Skeleton

# walktalk role -> role of the shared rig table (its "shoulder" role is the upper arm)
ROLES = {
    "hips": "hips", "spine": "spine", "neck": "neck", "head": "head",
    **{f"{k}_{s}": f"{full}_{v}" for s, full in (("l", "left"), ("r", "right"))
       for k, v in (("shoulder", "collar"), ("upperarm", "shoulder"), ("elbow", "elbow"), ("hand", "hand"),
                    ("upleg", "upleg"), ("foot", "foot"), ("toes", "toes"))},
}


@dataclass(frozen=True)
class Body:
    """Joint indices of one skeleton. ``parts`` maps part name -> tuple of joint indices."""

    joints: dict
    lower: tuple[int, ...]
    torso: tuple[int, ...]
    arm_l: tuple[int, ...]
    arm_r: tuple[int, ...]

    def arm(self, side: str) -> tuple[int, ...]:
        return self.arm_l if side == "l" else self.arm_r


def _subtree(skel: Skeleton, j: int) -> list[int]:
    out = [j]
    for k in range(j + 1, skel.num_joints):
        if skel.parents[k] in out:
            out.append(k)
    return out


def find_body(skel: Skeleton, path: str | None = None) -> Body:
    """Locate the parts of ``skel``; a :class:`WalkTalkError` lists every joint not found. A rig
    without toe joints uses its ankles as toes (foot contacts then come from the ankle alone)."""
    joints, missing = {}, []
    for key, role in ROLES.items():
        j = find_role(skel, role)
        if j is None and key.startswith("toes_"):   # no toe joint (GENEA): contacts from the ankle alone
            j = joints.get(f"foot_{key[-1]}")
        if j is None:
            missing.append(f"{key} ({role})")
        joints[key] = j
    if missing:
        raise WalkTalkError(f"skeleton lacks joints {missing} (patterns in convsynth_jax.rig.RIG_JOINTS); "
                            f"joints are {list(skel.names)}", path)
    arm_l = tuple(_subtree(skel, joints["shoulder_l"]))
    arm_r = tuple(_subtree(skel, joints["shoulder_r"]))
    legs = set(_subtree(skel, joints["upleg_l"])) | set(_subtree(skel, joints["upleg_r"]))
    spine_chain = set(_subtree(skel, joints["spine"]))
    lower = tuple(sorted(legs | {j for j in range(skel.num_joints) if j not in spine_chain and j not in legs}))
    torso = tuple(sorted(spine_chain - set(arm_l) - set(arm_r)))
    return Body(joints, lower, torso, arm_l, arm_r)


def check_same_skeleton(a: Skeleton, b: Skeleton, path_a: str, path_b: str) -> None:
    """Raise a :class:`WalkTalkError` listing missing / extra / reparented joints of ``b`` vs ``a``."""
    if a.names == b.names and a.parents == b.parents:
        return
    missing = [n for n in a.names if n not in b.names]
    extra = [n for n in b.names if n not in a.names]
    moved = [n for n in a.names if n in b.names and
             (a.parents[a.index(n)] >= 0 and (b.parents[b.index(n)] < 0 or
              a.names[a.parents[a.index(n)]] != b.names[b.parents[b.index(n)]]))]
    order = [] if (missing or extra or moved) else ["joint order differs"]
    raise WalkTalkError(f"skeleton does not match {path_a}: missing joints {missing}, extra joints {extra}, "
                        f"different parents {moved} {' '.join(order)}".strip(), path_b)


def mask(num_joints: int, idx) -> np.ndarray:
    m = np.zeros(num_joints, dtype=bool)
    m[list(idx)] = True
    return m
