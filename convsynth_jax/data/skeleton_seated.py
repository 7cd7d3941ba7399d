"""A seated skeleton (28 joints, Mixamo-like names, centimetres, Y up, facing +Z) and its base pose.

The rest pose (all local rotations identity) is already seated with the arms hanging down; the
base pose bends the elbows so the forearms rest forward as on a table.
"""
from __future__ import annotations

import numpy as np

from ..skeleton import Skeleton

ROOT_CH = ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")
ROT_CH = ("Zrotation", "Xrotation", "Yrotation")

# name, parent name, offset (cm) for a reference body of scale 1.0
_JOINTS = [
    ("Hips", None, (0.0, 0.0, 0.0)),
    ("Spine", "Hips", (0.0, 10.0, 0.0)),
    ("Spine1", "Spine", (0.0, 12.0, 0.0)),
    ("Spine2", "Spine1", (0.0, 12.0, 0.0)),
    ("Neck", "Spine2", (0.0, 14.0, 0.0)),
    ("Head", "Neck", (0.0, 9.0, 1.0)),
    ("LeftShoulder", "Spine2", (4.0, 11.0, 0.0)),
    ("LeftArm", "LeftShoulder", (13.0, 0.0, 0.0)),
    ("LeftForeArm", "LeftArm", (0.0, -28.0, 0.0)),
    ("LeftHand", "LeftForeArm", (0.0, -25.0, 0.0)),
    ("LeftHandThumb1", "LeftHand", (2.0, -3.0, 2.0)),
    ("LeftHandIndex1", "LeftHand", (1.5, -9.0, 1.0)),
    ("LeftHandMiddle1", "LeftHand", (0.0, -9.5, 0.0)),
    ("RightShoulder", "Spine2", (-4.0, 11.0, 0.0)),
    ("RightArm", "RightShoulder", (-13.0, 0.0, 0.0)),
    ("RightForeArm", "RightArm", (0.0, -28.0, 0.0)),
    ("RightHand", "RightForeArm", (0.0, -25.0, 0.0)),
    ("RightHandThumb1", "RightHand", (-2.0, -3.0, 2.0)),
    ("RightHandIndex1", "RightHand", (-1.5, -9.0, 1.0)),
    ("RightHandMiddle1", "RightHand", (0.0, -9.5, 0.0)),
    ("LeftUpLeg", "Hips", (9.0, -4.0, 0.0)),
    ("LeftLeg", "LeftUpLeg", (0.0, 0.0, 42.0)),
    ("LeftFoot", "LeftLeg", (0.0, -44.0, 0.0)),
    ("LeftToeBase", "LeftFoot", (0.0, -5.0, 12.0)),
    ("RightUpLeg", "Hips", (-9.0, -4.0, 0.0)),
    ("RightLeg", "RightUpLeg", (0.0, 0.0, 42.0)),
    ("RightFoot", "RightLeg", (0.0, -44.0, 0.0)),
    ("RightToeBase", "RightFoot", (0.0, -5.0, 12.0)),
]
# End Sites: the head's is a point on the forehead (forward and up), used to measure nods.
_END_SITES = {"Head": (0.0, 9.0, 9.0), "LeftHandThumb1": (1.5, -3.0, 1.5), "LeftHandIndex1": (0.0, -4.0, 0.0),
              "LeftHandMiddle1": (0.0, -4.5, 0.0), "RightHandThumb1": (-1.5, -3.0, 1.5),
              "RightHandIndex1": (0.0, -4.0, 0.0), "RightHandMiddle1": (0.0, -4.5, 0.0),
              "LeftToeBase": (0.0, 0.0, 5.0), "RightToeBase": (0.0, 0.0, 5.0)}

NAMES = tuple(j[0] for j in _JOINTS)
INDEX = {n: i for i, n in enumerate(NAMES)}
SEAT_HEIGHT = 48.0  # hips height above the floor, cm


def seated_skeleton(scale: float = 1.0) -> Skeleton:
    parents = tuple(-1 if p is None else INDEX[p] for _, p, _ in _JOINTS)
    offsets = np.array([o for _, _, o in _JOINTS], dtype=np.float64) * scale
    channels = tuple(ROOT_CH if p is None else ROT_CH for _, p, _ in _JOINTS)
    ends = tuple((INDEX[n], tuple(float(v) * scale for v in off)) for n, off in _END_SITES.items())
    ends = tuple(sorted(ends))
    return Skeleton(NAMES, parents, offsets, channels, ends)


def base_pose_degrees() -> np.ndarray:
    """(J, 3) Euler angles in channel order (Z, X, Y) degrees of the neutral seated pose."""
    e = np.zeros((len(NAMES), 3))
    for side, sgn in (("Left", 1.0), ("Right", -1.0)):
        e[INDEX[f"{side}Arm"]] = (sgn * 8.0, -22.0, 0.0)      # upper arm slightly forward and out
        e[INDEX[f"{side}ForeArm"]] = (0.0, -72.0, 0.0)        # forearm forward, resting on the table
        e[INDEX[f"{side}Hand"]] = (0.0, 10.0, 0.0)
        e[INDEX[f"{side}HandIndex1"]] = (0.0, -15.0, 0.0)
        e[INDEX[f"{side}HandMiddle1"]] = (0.0, -20.0, 0.0)
    e[INDEX["Neck"]] = (0.0, 4.0, 0.0)
    return e
