"""The evaluation's clip library: loops per gait, standing gestures with their phases, and the arm
DOFs and hand-torso distances of every clip found, from which the joint-limit table (the range of
motion, :func:`dof_limits`) and the torso check are calibrated; and splices placed on the library
(:func:`peak_placed_splices`)."""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..errors import MissingFileError, WalkTalkError
from ..io.bvh import load_bvh
from ..skeleton import Motion
from ..kinematics import forward_kinematics_np
from .body import Body, check_same_skeleton, find_body
from .gestures import apply_phase_override, load_phase_table, make_gesture
from .locomotion import extract_loop, tile_contact, tile_loop
from .params import WalkTalkParams
from .pipeline import GestureContext, LoopContext, gesture_context, loop_context, share_gait_band
from .splice import JointLimits, arm_joints, joint_euler, joint_limits
from .torso import hand_torso_distance

log = logging.getLogger(__name__)


@dataclass
class Library:
    body: Body
    loops: dict                       # gait -> list[LoopContext]
    gestures: list                    # list[GestureContext]
    skipped: list = field(default_factory=list)
    source_euler: list = field(default_factory=list)   # arm DOFs (F, A, 3) of every source clip, for limits
    source_kind: list = field(default_factory=list)    # "walk" | "jog" | "gesture", one per source_euler entry
    source_torso: list = field(default_factory=list)   # (F, 2) hands' distance to the torso axis, one per source clip


def resolve_data_dir(p: WalkTalkParams, repo_root: Path) -> Path:
    """``walktalk.data_dir``; empty = ../shared/data/bandai2/bvh beside the checkout, falling back to
    the small fixtures in tests/data/walktalk (with a warning) when the shared folder is absent."""
    if p.data_dir:
        d = Path(p.data_dir)
        if not d.is_dir():
            raise MissingFileError("walktalk.data_dir is not a folder", d)
        return d
    shared = repo_root.parent / "shared" / "data" / "bandai2" / "bvh"
    if shared.is_dir():
        return shared
    fixtures = repo_root / "tests" / "data" / "walktalk"
    log.warning("shared data %s absent: using the small fixtures in %s", shared, fixtures)
    return fixtures


def _spread(files: list, k: int) -> list:
    if len(files) <= k:
        return files
    idx = np.unique(np.linspace(0, len(files) - 1, k).round().astype(int))
    return [files[i] for i in idx]


def load_library(p: WalkTalkParams, data_dir: Path, loops_per_gait: int, max_gestures: int | None = None,
                 single_peak_only: bool = False) -> Library:
    """Loops (``loops_per_gait`` per gait, files spread over the sorted list; clips with too few
    cycles are skipped and reported) and gestures (all matching clips, phases detected, the CSV
    override applied). ``source_euler`` (the joint-limit table's input) holds the arm DOFs of every
    walk, run and gesture clip found, multi-peak gestures included, plus the ``limit_globs`` clips
    (walk-turns); with ``max_gestures`` only the gestures loaded. ``source_torso`` holds the same
    clips' hand distances to the torso axis (``torso.hand_torso_distance``), from which the torso
    check is calibrated (``evaluate.torso_radius``)."""
    data_dir = Path(data_dir)
    body, ref, loops, skipped, source, kinds, torso = None, None, {}, [], [], [], []
    for gait, pattern in (("walk", p.walk_glob), ("jog", p.jog_glob)):
        files = sorted(data_dir.glob(pattern))
        if not files:
            raise MissingFileError(f"no {gait} clips matching {pattern!r}", data_dir)
        got = []
        chosen = set(_spread(files, loops_per_gait))
        for f in files:
            m = load_bvh(f, fps=p.fps)
            if ref is None:
                ref, body = m, find_body(m.skeleton, str(f))
            check_same_skeleton(ref.skeleton, m.skeleton, ref.name, str(f))
            source.append(joint_euler(m, arm_joints(body)))
            torso.append(hand_torso_distance(forward_kinematics_np(m), body))
            kinds.append(gait)
            if f not in chosen:
                continue
            try:
                lp = extract_loop(m, p.gait, body)
            except WalkTalkError as e:
                skipped.append(str(e))
                continue
            got.append(loop_context(lp, body))
        loops[gait] = share_gait_band(got)   # used only with splice.band_std=gait_min
    gfiles = sorted({f for g in p.gesture_globs for f in data_dir.glob(g)})
    if max_gestures is not None and not single_peak_only:
        gfiles = _spread(gfiles, max_gestures)   # a sample across gesture kinds
    table = load_phase_table(p.phases_csv) if p.phases_csv else None
    gestures = []
    for f in gfiles:
        m = load_bvh(f, fps=p.fps)
        check_same_skeleton(ref.skeleton, m.skeleton, ref.name, str(f))
        source.append(joint_euler(m, arm_joints(body)))
        torso.append(hand_torso_distance(forward_kinematics_np(m), body))
        kinds.append("gesture")
        g = make_gesture(m, p.gait, p.phases, body)
        if table is not None:
            g = apply_phase_override(g, table, p.phases_csv)
        if single_peak_only and not g.single_peak:
            continue
        gestures.append(gesture_context(g, body, round(p.splice.transition_pad_s * p.fps)))
        if max_gestures is not None and len(gestures) >= max_gestures:
            break
    # clips for the joint-limit table only (walk-turns): "per-DOF percentiles over all clips"
    seen = {f for pattern in (p.walk_glob, p.jog_glob) for f in data_dir.glob(pattern)} | set(gfiles)
    for f in sorted({f for g in p.limit_globs for f in data_dir.glob(g)} - seen):
        m = load_bvh(f, fps=p.fps)
        check_same_skeleton(ref.skeleton, m.skeleton, ref.name, str(f))
        source.append(joint_euler(m, arm_joints(body)))
        torso.append(hand_torso_distance(forward_kinematics_np(m), body))
        kinds.append("limits only")
    return Library(body, loops, gestures, skipped, source, kinds, torso)


def dof_limits(lib: Library, percentiles=(0.5, 99.5), tolerance_deg: float = 0.0) -> JointLimits:
    """Limits over every source clip loaded (all locomotion and gesture clips found, not only the
    loops and gestures chosen for the evaluation)."""
    return joint_limits(lib.source_euler, arm_joints(lib.body), percentiles, tolerance_deg)


class PlacedSplice(NamedTuple):
    """One gesture x loop set up for a splice (:func:`peak_placed_splices`): ``frames`` the
    timeline's length, ``utterance_peak_s`` the stress peak it serves (s), ``loco`` the loop tiled
    over the timeline and ``contact`` its (frames,) contact labels."""

    gesture: GestureContext
    gait: str
    loop: LoopContext
    frames: int
    utterance_peak_s: float
    loco: Motion
    contact: np.ndarray


def peak_placed_splices(lib: Library, p: WalkTalkParams, gestures=None):
    """Every gesture (default: the library's) x every loaded loop, set up for a splice whose stroke
    peak falls one loop length plus 20 frames into a timeline of the gesture plus two loops:
    yields :class:`PlacedSplice`."""
    for gc in (lib.gestures if gestures is None else gestures):
        g = gc.gesture
        for gait, lcs in lib.loops.items():
            for lc in lcs:
                n = lc.loop.num_frames
                T = g.motion.num_frames + 2 * n + 40
                u = (n + 20 + g.phases.peaks[0]) / p.fps + p.splice.lead_s
                yield PlacedSplice(gc, gait, lc, T, u, tile_loop(lc.loop, T), tile_contact(lc.loop, T))
