"""The scaling database (graph/scale_db.py, task make_scale_db): exact size, reproducible, variants
that are what they claim, audio status from the synthetic plan, real clips when present."""
import shutil

import numpy as np
import pytest

from convsynth_jax.graph.scale_db import LATERAL_AXIS, ROLES, ScaleDBParams, bandai_clips, make_scale_database

from conftest import shared_path

SMALL = dict(frames=2500, seed=3, session_seconds=10.0, calibrate=False)


@pytest.fixture(scope="module")
def synthetic_db():
    return make_scale_database(ScaleDBParams(**SMALL))


def test_exact_size_reproducible_with_variants(synthetic_db):
    db = synthetic_db
    assert db.num_frames == SMALL["frames"] and db.positions.shape == (SMALL["frames"], len(ROLES), 3)
    again = make_scale_database(ScaleDBParams(**SMALL))
    np.testing.assert_array_equal(db.positions, again.positions)
    np.testing.assert_array_equal(db.own.label, again.own.label)
    assert db.meta["scale_db"]["bandai_frames"] == 0
    names = list(db.clip_names)
    assert {n.split("#")[-1] for n in names if "#" in n} >= {"mirror", "warp"}
    # a mirror is the original with X negated and left/right roles swapped
    o = names.index(names[0] + "#mirror")
    P0 = db.positions[db.offsets[0]:db.offsets[1]]
    P1 = db.positions[db.offsets[o]:db.offsets[o + 1]]
    li, ri = ROLES.index("left_hand"), ROLES.index("right_hand")
    np.testing.assert_allclose(P1[:, li, LATERAL_AXIS], -P0[:, ri, LATERAL_AXIS])
    np.testing.assert_allclose(P1[:, li, 1], P0[:, ri, 1])
    # a warped clip has another length, and its velocities are differences of its positions
    w = names.index(names[0] + "#warp")
    n0, nw = np.diff(db.offsets)[[0, w]]
    assert nw != n0
    Pw = db.positions[db.offsets[w]:db.offsets[w + 1]]
    np.testing.assert_allclose(db.velocities[db.offsets[w]:db.offsets[w + 1]], np.gradient(Pw, axis=0) * 30.0,
                               rtol=1e-4, atol=1e-3)
    # the synthetic sessions carry their planted own and partner audio status
    assert set(np.unique(db.own.label)) >= {0, 1} and (db.partner.label > 0).any()


def test_real_clips_first_when_present(tmp_path):
    src = shared_path("bandai2", "bvh")
    files = sorted(src.glob("*.bvh"))[:2] if src.is_dir() else []
    if not files:
        pytest.skip("shared Bandai data not available")
    for f in files:
        shutil.copy(f, tmp_path / f.name)
    real = bandai_clips(tmp_path, 30.0)
    frames = 3 * sum(len(c.P) for c in real)  # originals, mirrors and some warps: no synthetic session needed
    db = make_scale_database(ScaleDBParams(**{**SMALL, "frames": frames, "bandai_root": str(tmp_path)}))
    assert db.clip_names[0].startswith("bandai/") and db.meta["scale_db"]["synthetic_sessions"] == 0
    assert db.num_frames == frames and db.meta["scale_db"]["bandai_frames"] == frames // 3
    assert bandai_clips(tmp_path / "absent", 30.0) == []  # no folder: synthetic motion only
