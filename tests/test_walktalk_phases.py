"""Contact and flight phases by the paper's definition (Sec. 3.1): planted walks and jogs with known
heel strikes, double support and leg passing, the bandai2 fixtures, and the shared recordings."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from convsynth_jax.errors import WalkTalkError
from convsynth_jax.io.bvh import load_bvh
from convsynth_jax.kinematics import forward_kinematics_np
from convsynth_jax.walktalk.body import find_body
from convsynth_jax.walktalk.locomotion import (
    contact_phases,
    detect_gait,
    extract_loop,
    foot_tracks,
    tile_contact,
)
from convsynth_jax.walktalk.params import GaitParams
from convsynth_jax.walktalk.planted_clips import synthetic_jog, synthetic_walk

FIXTURES = Path(__file__).resolve().parent / "data" / "walktalk"


def _runs(mask):
    m = np.concatenate([[False], mask, [False]]).astype(int)
    d = np.diff(m)
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def _check_walk_phases(contact, strikes, passing, lo=0.35, hi=0.65):
    """Contact is a window around each heel strike: every strike frame is contact, the frames where
    one leg passes the other (the crossing frame and the one before it) are flight, and every
    contact run inside the clip holds exactly one heel strike."""
    n = len(contact)
    for s in strikes:
        assert contact[s], f"heel strike at frame {s} labelled flight"
    for x in passing:
        for t in (x - 1, x):
            if 0 <= t < n:
                assert not contact[t], f"legs pass each other at frame {t} but it is labelled contact"
    for a, b in _runs(contact):
        if a > 0 and b < n:
            inside = [s for s in strikes if a <= s < b]
            assert len(inside) == 1, f"contact run {a}-{b} holds heel strikes {inside}"
    assert lo <= contact.mean() <= hi, contact.mean()


def test_walking_contact_is_a_window_around_each_heel_strike_planted():
    """Defect: walking contact was the front foot down or landing, so it lasted from the
    landing until the trailing leg had swung past: the frames where one leg passes the other (the
    paper's flight) were contact. Planted walk: strikes every 16 frames, 60% duty (double support),
    the swing ankle overtakes the stance ankle 10 frames after each strike."""
    m, truth = synthetic_walk(periods=3.5)
    g = detect_gait(m, GaitParams())
    assert g.gait == "walk"
    assert g.strikes_l == truth["strikes_l"] and g.strikes_r == truth["strikes_r"]
    np.testing.assert_array_equal(g.down_l, truth["down_l"])
    np.testing.assert_array_equal(g.down_r, truth["down_r"])
    strikes = sorted(truth["strikes_l"] + truth["strikes_r"])
    _check_walk_phases(g.contact, strikes, truth["passing"])
    # the second reading (feet apart) agrees on the strikes and the passing frames
    _check_walk_phases(g.contact_alt, strikes, truth["passing"], 0.35, 0.75)
    # double support (both feet down) is always contact
    both = truth["down_l"] & truth["down_r"]
    assert g.contact[both].all()
    # the loop is relabelled from its own frames: it starts at left contact
    lp = extract_loop(m, GaitParams())
    assert lp.contact[0] and lp.contact_alt is not None
    _check_walk_phases(lp.contact, [s - lp.start for s in strikes if lp.start <= s < lp.start + lp.num_frames],
                       [x - lp.start for x in truth["passing"] if lp.start <= x < lp.start + lp.num_frames])
    np.testing.assert_array_equal(tile_contact(lp, 3 * lp.num_frames, second=True)[lp.num_frames:2 * lp.num_frames],
                                  lp.contact_alt)


def test_jogging_contact_is_a_foot_on_the_ground_planted():
    """Jogging: contact = at least one foot down (the primary reading equals the planted down
    frames); the second, height-only reading contains them and adds only frames of a foot within
    10% of its swing clearance."""
    m, truth = synthetic_jog(periods=3.5)
    p = GaitParams()
    g = detect_gait(m, p)
    assert g.gait == "jog"
    np.testing.assert_array_equal(g.contact, truth["contact"])
    assert g.contact_alt[truth["contact"]].all()
    extra = g.contact_alt & ~truth["contact"]
    tracks = foot_tracks(forward_kinematics_np(m), find_body(m.skeleton))
    low = np.minimum(tracks.low_l / tracks.low_l.max(), tracks.low_r / tracks.low_r.max())
    assert (low[extra] <= p.jog_ground_frac + 1e-9).all()
    assert 0.0 < g.contact.mean() < 1.0


def test_phase_thresholds_scale_with_the_motion():
    """Thresholds come from the labelled frames: scaling every foot height and the separation by
    the same factor leaves the labels unchanged."""
    m, _ = synthetic_walk(periods=3.5)
    pos = forward_kinematics_np(m)
    t = foot_tracks(pos, find_body(m.skeleton))
    g = detect_gait(m, GaitParams())
    p = GaitParams()
    scaled = type(t)(t.low_l * 3.0, t.low_r * 3.0, t.separation * 3.0)
    for gait in ("walk", "jog"):
        a = contact_phases(t, g.down_l, g.down_r, gait, p)
        b = contact_phases(scaled, g.down_l, g.down_r, gait, p)
        for x, y in zip(a, b):
            np.testing.assert_array_equal(x, y)


def test_phase_fraction_parameters_are_checked():
    for name in ("near_ground_frac", "pass_frac", "jog_ground_frac"):
        with pytest.raises(WalkTalkError, match=f"walktalk.gait.{name}"):
            GaitParams(**{name: 1.5})


def test_walking_phases_on_fixture():
    """The bandai2 walk excerpt: contact 35-65% of frames, every heel strike in contact, the
    frames where the ankles cross (one leg passing the other) in flight."""
    m = load_bvh(next(FIXTURES.glob("*_walk_normal_*.bvh")))
    g = detect_gait(m, GaitParams())
    assert g.gait == "walk"
    ahead = g.separation > 0
    passing = tuple(int(i) for i in np.flatnonzero(ahead[1:] != ahead[:-1]) + 1)
    assert len(passing) >= 3
    _check_walk_phases(g.contact, sorted(g.strikes_l + g.strikes_r), passing)


def test_contact_fractions_on_shared_loops(bandai_dir):
    """Every bandai2 walk loop: contact 35-65% of frames; every run loop: contact = a foot down,
    and the height-only reading agrees on >= 80% of frames."""
    p = GaitParams()
    fr = {"walk": [], "jog": []}
    for pattern in ("*_walk_normal_*.bvh", "*_run_normal_*.bvh"):
        for f in sorted(bandai_dir.glob(pattern))[::4]:
            m = load_bvh(f, fps=30.0)
            b = find_body(m.skeleton, str(f))
            try:
                lp = extract_loop(m, p, b)
            except Exception:    # a clip with too few cycles is skipped by the library as well
                continue
            fr[lp.gait].append(lp.contact.mean())
            if lp.gait == "jog":
                g = detect_gait(m, p, b)
                a, n = lp.start, lp.num_frames
                np.testing.assert_array_equal(lp.contact, (g.down_l | g.down_r)[a:a + n])
                assert (lp.contact == lp.contact_alt).mean() >= 0.8
    assert len(fr["walk"]) >= 5 and len(fr["jog"]) >= 10
    assert all(0.35 <= x <= 0.65 for x in fr["walk"]), fr["walk"]
