"""Walk the Talk finds its body parts through the shared rig table (convsynth_jax.rig.RIG_JOINTS):
the joints chosen on SMPL-X, CMU, Mixamo, GENEA, BEAT and Bandai trees, and the part split."""
from __future__ import annotations

import pytest
from rigs import RIG_TREES, rig_skeleton

from convsynth_jax.rig import DEFAULT_JOINTS, RIG_JOINTS, find_joints
from convsynth_jax.errors import WalkTalkError
from convsynth_jax.walktalk import body as body_mod
from convsynth_jax.walktalk.body import ROLES, find_body

# per rig: clavicle, forearm, hand, up-leg, foot, toes (left side), hips, spine
EXPECTED_BODY = {
    "smplx": ("left_collar", "left_elbow", "left_wrist", "left_hip", "left_ankle", "left_foot", "pelvis", "spine1"),
    "cmu": ("LeftShoulder", "LeftForeArm", "LeftHand", "LeftUpLeg", "LeftFoot", "LeftToeBase", "Hips", "Spine"),
    "mixamo": ("mixamorig:LeftShoulder", "mixamorig:LeftForeArm", "mixamorig:LeftHand", "mixamorig:LeftUpLeg",
               "mixamorig:LeftFoot", "mixamorig:LeftToeBase", "mixamorig:Hips", "mixamorig:Spine"),
    "genea": ("b_l_shoulder", "b_l_forearm", "b_l_wrist", "b_l_upleg", "b_l_foot", "b_l_foot", "b_root", "b_spine0"),
    "beat": ("LeftShoulder", "LeftForeArm", "LeftHand", "LeftUpLeg", "LeftFoot", "LeftToeBase", "Hips", "Spine"),
    "bandai": ("Shoulder_L", "LowerArm_L", "Hand_L", "UpperLeg_L", "Foot_L", "Toes_L", "Hips", "Spine"),
}
KEYS = ("shoulder_l", "elbow_l", "hand_l", "upleg_l", "foot_l", "toes_l", "hips", "spine")


def test_walktalk_has_no_pattern_table_of_its_own():
    assert set(ROLES.values()) <= set(RIG_JOINTS)
    own = [k for k, v in vars(body_mod).items() if isinstance(v, dict) and v is not RIG_JOINTS
           and k not in ("ROLES", "__builtins__")]
    assert own == []
    assert set(DEFAULT_JOINTS) <= set(RIG_JOINTS)


@pytest.mark.parametrize("rig", sorted(RIG_TREES))
def test_find_body_on_each_rig(rig):
    skel = rig_skeleton(rig)
    b = find_body(skel, rig)
    assert tuple(skel.names[b.joints[k]] for k in KEYS) == EXPECTED_BODY[rig]
    # the upper arm and hand agree with the annotation's six roles (one table, one answer)
    six = find_joints(skel)
    assert b.joints["upperarm_l"] == six["left_shoulder"] and b.joints["hand_r"] == six["right_hand"]
    assert b.joints["neck"] == six["neck"] and b.joints["head"] == six["head"]
    # parts: the hands in their arms, the feet in the lower body, neck and head in the torso
    assert b.joints["hand_l"] in b.arm_l and b.joints["hand_r"] in b.arm_r
    assert {b.joints["foot_l"], b.joints["foot_r"], b.joints["hips"]} <= set(b.lower)
    assert {b.joints["neck"], b.joints["head"]} <= set(b.torso)
    parts = [set(b.lower), set(b.torso), set(b.arm_l), set(b.arm_r)]
    assert sum(len(p) for p in parts) == skel.num_joints == len(set().union(*parts))


def test_missing_joints_listed_with_shared_roles():
    skel = rig_skeleton("cmu")
    names = tuple("LeftPaw" if n == "LeftHand" else n for n in skel.names)
    import dataclasses

    with pytest.raises(WalkTalkError, match=r"hand_l \(left_hand\)") as e:
        find_body(dataclasses.replace(skel, names=names), "cmu.bvh")
    assert "cmu.bvh" in str(e.value) and "LeftPaw" in str(e.value)


@pytest.mark.parametrize("rig", sorted(RIG_TREES))
def test_cdbn_finds_head_and_arms_through_the_rig_table(rig):
    """The CDBN's head and arm joints are rig roles (cdbn.features), so its default finds them on every
    rig the table knows, and they are the joints annotation and Walk the Talk take for those roles."""
    from convsynth_jax.cdbn.features import head_joint_indices
    from convsynth_jax.cdbn.hands import arm_rig
    from convsynth_jax.cdbn.params import CDBNFeatureParams

    skel = rig_skeleton(rig)
    fp = CDBNFeatureParams()
    six, b = find_joints(skel), find_body(skel, rig)
    assert head_joint_indices(skel, fp.head_joints) == [six["neck"], six["head"]]
    assert arm_rig(skel, fp).joints == (b.joints["upperarm_l"], b.joints["elbow_l"], b.joints["upperarm_r"],
                                        b.joints["elbow_r"])
