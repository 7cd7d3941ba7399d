"""Figures of the walk-the-talk evaluation, drawn from the evaluation table (object-oriented
matplotlib, no pyplot state): gesture peak vs gait phase, elbow bend loop vs stroke, a contact
sheet of one splice, and the contact/flight phases of a walk and a jog loop. Each returns the Figure;
``task=walktalk_eval`` writes it with ``figures.save_figure``."""
from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from ...kinematics import forward_kinematics_np
from ...skeleton import Motion
from ..panels import label_panel


def peak_phase_figure(df: pd.DataFrame) -> Figure:
    """Histogram of the stroke peak's position in the gait cycle (0 = left contact), per gait and
    method; the share of peaks in contact is in each legend."""
    gaits = list(dict.fromkeys(df["gait"]))
    methods = list(dict.fromkeys(df["method"]))
    fig = Figure(figsize=(4.5 * len(gaits), 3.4))
    bins = np.linspace(0, 1, 21)
    for i, gait in enumerate(gaits):
        ax = fig.add_subplot(1, len(gaits), i + 1)
        for m in methods:
            d = df[(df["gait"] == gait) & (df["method"] == m)]
            ax.hist(d["gait_phase"], bins=bins, histtype="step", lw=1.5,
                    label=f"{m} ({100 * d['peak_in_contact'].mean():.0f}% in contact)")
        label_panel(ax, f"{gait}: stroke peak vs gait phase", "splices", "phase in the two-cycle loop (0 = left contact)")
    fig.tight_layout()
    return fig


def elbow_bend_figure(df: pd.DataFrame) -> Figure:
    """Per method, the stroke's elbow bend against the loop's mean elbow bend (degrees), per gait."""
    methods = list(dict.fromkeys(df["method"]))
    fig = Figure(figsize=(4 * len(methods), 3.6))
    for i, m in enumerate(methods):
        ax = fig.add_subplot(1, len(methods), i + 1)
        d = df[df["method"] == m]
        for gait, mk in (("walk", "o"), ("jog", "^")):
            e = d[d["gait"] == gait]
            ax.scatter(e["loop_elbow_bend_deg"], e["elbow_bend_deg"], s=6, marker=mk, alpha=0.5, label=gait)
        r = np.corrcoef(d["loop_elbow_bend_deg"], d["elbow_bend_deg"])[0, 1] if d["elbow_bend_deg"].std() > 0 else np.nan
        label_panel(ax, f"{m}: r = {r:.2f}", "stroke elbow bend (deg)", "loop mean elbow bend (deg)")
    fig.tight_layout()
    return fig


def splice_contact_sheet_figure(motions: dict[str, Motion], frames: list[int], title: str = "") -> Figure:
    """Side views (forward axis vs height) of a few frames, one row per motion (e.g. naive vs
    stylized+synced), each frame drawn around its own root."""
    rows = list(motions)
    fig = Figure(figsize=(1.6 * len(frames), 2.6 * len(rows)))
    for r, name in enumerate(rows):
        m = motions[name]
        pos = forward_kinematics_np(m)
        parents = m.skeleton.parents
        travel = pos[-1, 1] - pos[0, 1]
        fwd = 2 if abs(travel[2]) >= abs(travel[0]) else 0
        sign = 1.0 if travel[fwd] >= 0 else -1.0
        for c, f in enumerate(frames):
            ax = fig.add_subplot(len(rows), len(frames), r * len(frames) + c + 1)
            p = pos[f]
            x = sign * (p[:, fwd] - p[1, fwd])
            static_top = np.ptp(pos[:, 0], axis=0).max() < 1e-6  # bandai2's joint_Root stays at the origin
            for j, par in enumerate(parents):
                if par >= 0 and not (par == 0 and static_top):
                    arm = any(k in m.skeleton.names[j] for k in ("Arm", "Hand"))
                    ax.plot([x[par], x[j]], [p[par, 1], p[j, 1]], color="C3" if arm else "0.3", lw=1.5)
            ax.set_xlim(-70, 70)
            ax.set_ylim(-5, 200)
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(f"{name}\nframe {f}" if c == 0 else f"frame {f}", fontsize=7)
    if title:
        fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    return fig


def gait_phases_figure(panels: dict, gait_params=None) -> Figure:
    """Contact and flight phases of a few loops, one column per loop (e.g. one walk and one jog):
    the feet's lowest-point heights above the ground with the contact frames of the primary
    reading shaded (top), and below the quantity the second reading is taken from with its contact
    frames shaded: the feet's separation along the direction of travel (walk) or the heights again
    (jog) (``locomotion.contact_phases``).

    panels: title -> dict with ``low_l``, ``low_r``, ``separation``, ``contact``, ``contact_alt``
    (F,) arrays, ``gait`` and ``fps``; ``gait_params`` (``GaitParams``): draws the second
    reading's thresholds (walk: +- ``pass_frac`` of the step separation, the 95th percentile of the
    absolute separation; jog: ``jog_ground_frac`` of each foot's clearance)."""
    names = list(panels)
    fig = Figure(figsize=(5.2 * len(names), 4.6))
    labels = {"low_l": "left foot", "low_r": "right foot", "separation": "left ahead of right"}
    for c, name in enumerate(names):
        d = panels[name]
        t = np.arange(len(d["contact"])) / d["fps"]
        second = ("separation",) if d["gait"] == "walk" else ("low_l", "low_r")
        for r, (keys, mask, label) in enumerate(((("low_l", "low_r"), d["contact"], "contact"),
                                                 (second, d["contact_alt"], "contact, second reading"))):
            ax = fig.add_subplot(2, len(names), r * len(names) + c + 1)
            for k in keys:
                ax.plot(t, d[k], color={"low_l": "C0", "low_r": "C1", "separation": "C2"}[k], lw=1.3, label=labels[k])
            lo, hi = ax.get_ylim()
            ax.fill_between(t, lo, hi, where=np.asarray(mask, bool), step="mid", color="0.85", zorder=0,
                            label=f"{label} ({100 * np.mean(mask):.0f}%)")
            ax.set_ylim(lo, hi)
            if r == 1 and gait_params is not None:
                if d["gait"] == "walk":
                    step = np.percentile(np.abs(d["separation"]), 95)
                    for sgn in (-1, 1):
                        ax.axhline(sgn * gait_params.pass_frac * step, color="0.4", lw=0.8, ls="--")
                else:
                    for k, colour in (("low_l", "C0"), ("low_r", "C1")):
                        ax.axhline(gait_params.jog_ground_frac * d[k].max(), color=colour, lw=0.8, ls="--")
            ax.set_ylabel("separation (cm)" if keys == ("separation",) else "height above ground (cm)")
            if r == 0:
                ax.set_title(f"{name} ({d['gait']})", fontsize=9)
            else:
                ax.set_xlabel("time in the loop (s)")
            ax.legend(fontsize=6, loc="upper right")
    fig.tight_layout()
    return fig


def gait_phase_panel(loop, body, positions: np.ndarray | None = None) -> dict:
    """The arrays :func:`gait_phases_figure` draws for one loop (``positions``: its joint positions, (N, J, 3))."""
    from ...kinematics import forward_kinematics_np
    from ...walktalk.locomotion import foot_tracks

    tr = foot_tracks(forward_kinematics_np(loop.motion) if positions is None else positions, body)
    alt = loop.contact if loop.contact_alt is None else loop.contact_alt
    return {"low_l": tr.low_l, "low_r": tr.low_r, "separation": tr.separation, "contact": loop.contact,
            "contact_alt": alt, "gait": loop.gait, "fps": loop.motion.fps}

