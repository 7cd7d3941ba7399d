"""Joint roles of the known rigs: the one home for joint-name patterns.

A *role* is what a joint does in the body ("left_hand", "neck", "left_elbow", ...); a *rig* is a
naming convention (SMPL/SMPL-X, CMU, Mixamo, GENEA / Talking With Hands, Trinity, BEAT, Bandai,
Unreal, 3ds Max Biped). Every module that looks a joint up by what it does goes through this table:
annotation (hand and head speeds: the six roles of :data:`DEFAULT_JOINTS`, :func:`find_joints`),
Walk the Talk (body parts, retargeting, gaze: :func:`find_role`), the CDBN (head and arm streams:
role names in ``cdbn.features``), and the transition cost's finger weights (:data:`FINGER_PATTERN`).
The one configured list of joint names elsewhere is the gaze's per-joint yaw shares
(``walktalk.gaze.joint_shares``, ``lean_joint``), which name joints of the locomotion library's rig.

The module only reads a skeleton's ``names``, ``parents`` and ``find`` (``convsynth_jax.skeleton``),
so it sits below it.
"""
from __future__ import annotations

import re

from .errors import ConfigError

# Finger joints get weight 0 in the paper's transition cost (Eq. 4).
FINGER_PATTERN = r"(finger|thumb|index|middle|ring|pinky|little|hand_?(thumb|index|middle|ring|pinky))"

# A joint name may carry a namespace ("mixamorig:LeftHand", "mixamorig1:LeftHand", "Armature|Head"):
# every default pattern matches at the start of the name or right after ':' or '|', and ends with '$'
# so finger, twist and end joints (LeftHandThumb1, b_l_wrist_twist, Head_End, HeadTop_End, Neck1
# when Neck exists) are never taken. Patterns are tried in order over all joints (Skeleton.find).
_NS = r"(?:^|[:|])"


def _side(side: str) -> dict:
    """Hand and upper-arm patterns of one side ("l" or "r")."""
    full = {"l": "left", "r": "right"}[side]
    return {
        f"{full}_hand": [
            rf"{_NS}{full}_?hand$",                              # CMU, BEAT, Trinity, Mixamo, Rokoko
            rf"{_NS}(?:hand_{side}|{side}_?hand)$",              # Bandai Hand_L, Unreal hand_l, l_hand
            rf"{_NS}(?:{full}_?wrist|{side}_wrist)$",            # SMPL / SMPL-X left_wrist
            rf"^b_{side}_wrist$",                                # GENEA 2022/2023 (Talking With Hands)
            rf"^bip\d*[ _]{side}[ _]hand$",                      # 3ds Max Biped "Bip01 L Hand"
        ],
        # The shoulder role is the upper-arm joint: its parent's frame turns with the torso.
        f"{full}_shoulder": [
            rf"{_NS}{full}_?arm$",                               # CMU, BEAT, Trinity, Mixamo LeftArm
            rf"{_NS}(?:{full}_?upper_?arm|upper_?arm_{side}|{side}_?upper_?arm)$",  # Bandai UpperArm_L
            rf"^b_{side}_arm$",                                  # GENEA b_l_arm (b_l_shoulder = clavicle)
            rf"^bip\d*[ _]{side}[ _]upperarm$",                  # Biped
            rf"{_NS}(?-i:{full}_shoulder)$",                     # SMPL / SMPL-X: parent is left_collar
        ],
    }


DEFAULT_JOINTS = {
    **_side("l"),
    **_side("r"),
    "neck": [rf"{_NS}neck$", r"^b_neck0?$", rf"{_NS}neck_?0?1$", r"^bip\d*[ _]neck$"],
    "head": [rf"{_NS}head$", r"^b_head$", r"^bip\d*[ _]head$"],
}


def _body_side(side: str) -> dict:
    """Clavicle, forearm and leg patterns of one side (roles beyond the six of DEFAULT_JOINTS, for
    systems that need the whole body, e.g. convsynth_jax.walktalk). Same conventions as _side."""
    full = {"l": "left", "r": "right"}[side]
    return {
        f"{full}_collar": [
            rf"{_NS}{full}_?collar$",                            # SMPL / SMPL-X (its left_shoulder is the upper arm)
            rf"{_NS}(?:{full}_?shoulder|shoulder_{side}|{side}_shoulder)$",  # CMU, BEAT, Mixamo LeftShoulder; Bandai Shoulder_L
            rf"{_NS}(?:{full}_?clavicle|clavicle_{side}|{side}_?clavicle)$",  # Unreal clavicle_l
            rf"^b_{side}_shoulder$",                             # GENEA b_l_shoulder (the clavicle)
            rf"^bip\d*[ _]{side}[ _]clavicle$",                  # Biped
        ],
        f"{full}_elbow": [
            rf"{_NS}{full}_?fore_?arm$",                         # CMU, BEAT, Mixamo LeftForeArm
            rf"{_NS}(?:{full}_?lower_?arm|lower_?arm_{side}|{side}_?lower_?arm)$",  # Bandai LowerArm_L, Unreal lowerarm_l
            rf"{_NS}{full}_?elbow$",                             # SMPL / SMPL-X left_elbow
            rf"^b_{side}_forearm$",                              # GENEA
            rf"^bip\d*[ _]{side}[ _]forearm$",                   # Biped
        ],
        f"{full}_upleg": [
            rf"{_NS}{full}_?up_?leg$",                           # CMU, BEAT, Mixamo LeftUpLeg
            rf"{_NS}(?:{full}_?upper_?leg|upper_?leg_{side}|{side}_?upper_?leg)$",  # Bandai UpperLeg_L
            rf"{_NS}(?:{full}_?thigh|thigh_{side}|{side}_?thigh)$",  # Unreal thigh_l
            rf"{_NS}{full}_?hip$",                               # SMPL / SMPL-X left_hip
            rf"^b_{side}_upleg$",                                # GENEA
            rf"^bip\d*[ _]{side}[ _]thigh$",                     # Biped
        ],
        f"{full}_foot": [
            rf"{_NS}{full}_?ankle$",                             # SMPL / SMPL-X left_ankle (its left_foot is the toes)
            rf"{_NS}(?:{full}_?foot|foot_{side}|{side}_?foot)$",  # CMU, BEAT, Mixamo LeftFoot; Bandai Foot_L
            rf"^b_{side}_foot$",                                 # GENEA
            rf"^bip\d*[ _]{side}[ _]foot$",                      # Biped
        ],
        f"{full}_toes": [
            rf"{_NS}{full}_?toe_?base$",                         # CMU, BEAT, Mixamo LeftToeBase
            rf"{_NS}(?:{full}_?toes?|toes?_{side}|{side}_?toes?|ball_{side})$",  # Bandai Toes_L, Unreal ball_l
            rf"^bip\d*[ _]{side}[ _]toe0$",                      # Biped
            rf"{_NS}(?-i:{full}_foot)$",                         # SMPL / SMPL-X (lower case, after the ankle)
        ],
    }


# Whole-body roles on the same rigs (additive: find_joints keeps its six roles of DEFAULT_JOINTS).
BODY_JOINTS = {
    "hips": [rf"{_NS}hips$", rf"{_NS}pelvis$", r"^b_root$", r"^bip\d*[ _]pelvis$"],
    "spine": [rf"{_NS}spine$", rf"{_NS}spine_?0?1$", r"^b_spine0$", r"^bip\d*[ _]spine$"],
    **_body_side("l"),
    **_body_side("r"),
}
# Every role the project recognizes by joint name.
RIG_JOINTS = {**DEFAULT_JOINTS, **BODY_JOINTS}


def find_role(skeleton, role: str) -> int | None:
    """Index of the joint of ``skeleton`` that plays ``role`` (a key of :data:`RIG_JOINTS`): the first
    joint matching the role's first pattern that matches any joint (``Skeleton.find``); None if no
    pattern matches."""
    try:
        patterns = RIG_JOINTS[role]
    except KeyError:
        raise ConfigError(f"unknown joint role {role!r}; roles are {sorted(RIG_JOINTS)}") from None
    return skeleton.find(*patterns)


# Words that make a joint a plausible candidate for a role, listed when no pattern matched.
_ROLE_HINTS = {"left_hand": r"hand|hnd|wrist|wrst", "right_hand": r"hand|hnd|wrist|wrst", "left_shoulder": r"arm|shoulder|clav|collar",
               "right_shoulder": r"arm|shoulder|clav|collar", "neck": r"neck", "head": r"head"}
_OTHER_SIDE = {"left": re.compile(r"right|(^|[_:| ])r[_ ]|_r$|^R[A-Z]", re.IGNORECASE),
               "right": re.compile(r"left|(^|[_:| ])l[_ ]|_l$|^L[A-Z]", re.IGNORECASE)}
# Joints whose speeds are measured relative to another joint must lie below it in the tree.
_BELOW = {"left_hand": "left_shoulder", "right_hand": "right_shoulder", "head": "neck"}


def joint_override(role: str, joint_name: str) -> str:
    """The command-line override that selects ``joint_name`` for ``role``, quoted for Hydra (a regex
    with ^, $ or : must be a quoted string) inside single quotes for the shell (so $ stays)."""
    return f"'annotate.joints.{role}=\"^{re.escape(joint_name)}$\"'"


def _is_below(skeleton, j: int, ancestor: int) -> bool:
    while j >= 0:
        j = skeleton.parents[j]
        if j == ancestor:
            return True
    return False


def find_joints(skeleton, patterns: dict | None = None) -> dict:
    """{role: joint index} for the six roles of DEFAULT_JOINTS; ``patterns`` overrides a role's
    regex list (a None value keeps the default). Recognizes SMPL/SMPL-X, CMU, Mixamo, GENEA
    (Talking With Hands), Trinity, BEAT, Bandai, Unreal and Biped names. Raises ConfigError naming
    the missing role, the candidate joints and the override that selects one; also when a hand is not
    below its upper arm or the head not below the neck."""
    pats = {**DEFAULT_JOINTS, **{k: v for k, v in (patterns or {}).items() if v is not None}}
    unknown = set(pats) - set(DEFAULT_JOINTS)
    if unknown:
        raise ConfigError(f"unknown joint roles {sorted(unknown)}; expected {sorted(DEFAULT_JOINTS)}",
                          where="annotate.joints")
    out = {}
    for key, pl in pats.items():
        pl = [pl] if isinstance(pl, str) else list(pl)
        j = skeleton.find(*pl)
        if j is None:
            hint = re.compile(_ROLE_HINTS[key], re.IGNORECASE)
            other = _OTHER_SIDE.get(key.split("_")[0])
            cands = [n for n in skeleton.names if hint.search(n) and not (other and other.search(n))]
            example = joint_override(key, cands[0] if cands else skeleton.names[0])
            raise ConfigError(
                f"no joint for {key!r} (patterns {pl}); candidates {cands or 'none'} among "
                f"{list(skeleton.names)}; choose one on the command line with {example} "
                f"(Hydra needs the double quotes around a regex with ^, $ or :; the single quotes keep "
                f"the shell from expanding $)", where="annotate.joints")
        out[key] = j
    for key, above in _BELOW.items():
        if not _is_below(skeleton, out[key], out[above]):
            names = skeleton.names
            raise ConfigError(
                f"{key} joint {names[out[key]]!r} is not below the {above} joint {names[out[above]]!r} in the "
                f"hierarchy; set the right ones, e.g. {joint_override(above, names[out[above]])}",
                where="annotate.joints")
    return out


def resolve_joint(skeleton, entry: str) -> int | None:
    """A joint named in configuration: a role of :data:`RIG_JOINTS` (found by its patterns), else
    one or more exact joint names separated by ``|`` (the first present). None when nothing matches."""
    entry = str(entry)
    if entry in RIG_JOINTS:
        return find_role(skeleton, entry)
    for name in entry.split("|"):
        if name in skeleton.names:
            return skeleton.names.index(name)
    return None


# SMPL-X's 55 joints in the order of its pose vector (BEAT2's ``poses``: 55 x 3 axis-angle) and their
# parents (the model's kinematic tree): body 0-21, jaw 22, eyes 23-24, left hand 25-39, right hand 40-54.
_FINGERS = ("index", "middle", "pinky", "ring", "thumb")
SMPLX_JOINT_NAMES = (
    "pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2", "left_ankle",
    "right_ankle", "spine3", "left_foot", "right_foot", "neck", "left_collar", "right_collar", "head",
    "left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist",
    "jaw", "left_eye_smplhf", "right_eye_smplhf",
    *(f"{side}_{f}{k}" for side in ("left", "right") for f in _FINGERS for k in (1, 2, 3)),
)
SMPLX_PARENTS = (
    -1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 15, 15, 15,
    *(p for wrist, first in ((20, 25), (21, 40)) for f in range(5)
      for p in (wrist, first + 3 * f, first + 3 * f + 1)),
)
