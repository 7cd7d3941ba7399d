"""Joint roles on common rigs: the default patterns pick the exact joints on SMPL-X, CMU, Mixamo, GENEA,
BEAT and Bandai trees, never a finger, twist, end or second neck joint; a miss names the candidates and
an override Hydra accepts; task=cooccurrence runs on a GENEA-layout corpus of each rig without
overrides."""
import re

import numpy as np
import pandas as pd
import pytest
from rigs import EXPECTED, RIG_TREES, rig_skeleton, write_rig_corpus

from convsynth_jax.config import compose, run_task
from convsynth_jax.errors import ConfigError
from convsynth_jax.io import load_bvh
from convsynth_jax.rig import find_joints
from convsynth_jax.skeleton import Skeleton

ROLES = ("left_hand", "left_shoulder", "right_hand", "right_shoulder", "neck", "head")


def _chosen(skel):
    j = find_joints(skel)
    return tuple(skel.names[j[r]] for r in ROLES)


@pytest.mark.parametrize("rig", sorted(RIG_TREES))
def test_default_patterns_pick_each_rigs_joints(rig):
    skel = rig_skeleton(rig)
    assert _chosen(skel) == EXPECTED[rig]
    j = find_joints(skel)
    for hand, sh in (("left_hand", "left_shoulder"), ("right_hand", "right_shoulder")):
        # the upper arm's parent is the clavicle (collar), whose child chain reaches the hand
        assert skel.names[skel.parents[j[sh]]] in {"left_collar", "right_collar", "LeftShoulder", "RightShoulder",
                                                    "mixamorig:LeftShoulder", "mixamorig:RightShoulder",
                                                    "b_l_shoulder", "b_r_shoulder", "Shoulder_L", "Shoulder_R"}


def test_real_bandai_file_neck_and_head(tmp_path):
    from conftest import TEST_DATA

    skel = load_bvh(TEST_DATA / "dataset-2_raise-up-both-hands_normal_028.bvh").skeleton
    assert _chosen(skel) == EXPECTED["bandai"]


def _skeleton(names_parents):
    names = tuple(n for n, _ in names_parents)
    parents = tuple(names.index(p) if p else -1 for _, p in names_parents)
    return Skeleton(names, parents, np.ones((len(names), 3)), tuple(("Zrotation", "Xrotation", "Yrotation")
                                                                      for _ in names))


# A CMU-like tree listing the decoys before the real joints (Skeleton.find scans joints in order).
DECOYS = [("Hips", None), ("Spine", "Hips"), ("Neck1", "Spine"), ("Neck", "Spine"), ("HeadTop_End", "Neck"),
          ("Head_End", "Neck"), ("Head", "Neck"), ("LeftShoulder", "Spine"), ("LeftArm", "LeftShoulder"),
          ("LeftForeArm", "LeftArm"), ("LeftHandThumb1", "LeftForeArm"), ("LeftHandIndex1", "LeftForeArm"),
          ("LeftHand", "LeftForeArm"), ("RightShoulder", "Spine"), ("RightArm", "RightShoulder"),
          ("RightForeArm", "RightArm"), ("RightHand", "RightForeArm")]


def test_decoys_are_never_taken():
    assert _chosen(_skeleton(DECOYS)) == ("LeftHand", "LeftArm", "RightHand", "RightArm", "Neck", "Head")
    # without a LeftHand the thumb or index is not taken as the hand, the clavicle not as the arm
    no_hand = [(n, p) for n, p in DECOYS if n != "LeftHand"]
    with pytest.raises(ConfigError, match="no joint for 'left_hand'"):
        find_joints(_skeleton(no_hand))
    no_arm = [(n, "LeftShoulder" if p == "LeftArm" else p) for n, p in DECOYS if n != "LeftArm"]
    with pytest.raises(ConfigError, match="no joint for 'left_shoulder'"):
        find_joints(_skeleton(no_arm))


def test_hand_must_lie_below_its_upper_arm():
    skel = rig_skeleton("cmu")
    with pytest.raises(ConfigError, match="left_hand joint 'RightHand' is not below the left_shoulder"):
        find_joints(skel, {"left_hand": r"^RightHand$"})


def test_miss_lists_candidates_and_an_override_hydra_accepts():
    skel = _skeleton([("Root", None), ("Torso", "Root"), ("NeckA", "Torso"), ("Head", "NeckA"), ("L_Clav", "Torso"),
                      ("L_UpArm", "L_Clav"), ("L_LowArm", "L_UpArm"), ("L_Hnd", "L_LowArm"),
                      ("L_Wrist_Twist", "L_LowArm"), ("RightArm", "Torso"), ("RightHand", "RightArm")])
    with pytest.raises(ConfigError) as e:
        find_joints(skel)
    msg = str(e.value)
    assert "no joint for 'left_hand'" in msg and "candidates ['L_Hnd', 'L_Wrist_Twist']" in msg
    override = re.search(r"with '(annotate\.joints\.left_hand=\"[^\"]+\")'", msg).group(1)
    cfg = compose(["task=cooccurrence", override])
    assert skel.names[find_joints(skel, {"left_hand": cfg.annotate.joints.left_hand,
                                         "left_shoulder": "^L_UpArm$", "neck": "^NeckA$"})["left_hand"]] == "L_Hnd"
    # without Hydra's quotes the same regex does not parse
    with pytest.raises(Exception, match="annotate.joints.left_hand"):
        compose(["task=cooccurrence", override.replace('"', "")])


@pytest.mark.parametrize("rig", ["smplx", "cmu", "mixamo", "genea", "beat", "bandai"])
def test_cooccurrence_runs_on_each_rig_without_overrides(rig, tmp_path):
    root = write_rig_corpus(tmp_path / rig, rig)
    out = tmp_path / "out"
    cfg = compose(["task=cooccurrence", "corpus=genea", f"corpus.root={root}", f"cache_dir={tmp_path / 'cache'}",
                   "progress=false"])
    run_task(cfg, out)
    t = pd.read_csv(out / "cooccurrence.csv")
    assert len(t) == 10 and (t["total"] > 0).any()
    ev = pd.read_csv(out / "events.csv")
    assert set(ev["kind"]) <= {"LH", "RH", "Nod"} and len(ev) > 0


def test_smplx_joint_table_has_the_six_roles():
    """The SMPL-X table (55 joints in pose-vector order, parents before children) is recognized by
    the role patterns: wrists as hands, shoulders as upper arms, fingers weighted 0."""
    import numpy as np

    from convsynth_jax.rig import SMPLX_JOINT_NAMES, SMPLX_PARENTS, find_joints
    from convsynth_jax.skeleton import Skeleton

    assert len(SMPLX_JOINT_NAMES) == len(SMPLX_PARENTS) == 55
    assert SMPLX_JOINT_NAMES[25] == "left_index1" and SMPLX_JOINT_NAMES[54] == "right_thumb3"
    assert SMPLX_PARENTS[25] == 20 and SMPLX_PARENTS[27] == 26 and SMPLX_PARENTS[40] == 21
    sk = Skeleton(SMPLX_JOINT_NAMES, SMPLX_PARENTS, np.zeros((55, 3)), tuple(() for _ in range(55)))
    roles = {k: SMPLX_JOINT_NAMES[j] for k, j in find_joints(sk).items()}
    assert roles == {"left_hand": "left_wrist", "right_hand": "right_wrist", "left_shoulder": "left_shoulder",
                     "right_shoulder": "right_shoulder", "neck": "neck", "head": "head"}
    assert sk.joint_weights()[25:].sum() == 0 and sk.joint_weights()[:22].min() == 1
