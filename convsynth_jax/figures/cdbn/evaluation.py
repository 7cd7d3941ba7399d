"""Figures of the CDBN evaluation (Sadoughi & Busso; OO matplotlib, no global backend): Fig. 6
(state ellipses after random vs LBG initialization), Fig. 9 (validation CCA_m and LLR versus the
number of states) and an example of synthesized head trajectories with the constraint shaded. Each
returns the Figure; ``task=cdbn_eval`` writes it with ``figures.save_figure``."""
from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Ellipse


def init_ellipses_figure(data: np.ndarray, comparison: dict, dims=(0, 1), labels=("pitch (z)", "yaw (z)")) -> Figure:
    """The paper's Fig. 6: the motion-stream state ellipses after random and after LBG initialization
    over the data. data: (N, d_m) original motion (z-units); comparison: init_comparison output."""
    fig = Figure(figsize=(9, 4.2))
    for ax_i, init in enumerate(("random", "lbg")):
        ax = fig.add_subplot(1, 2, ax_i + 1)
        sub = data[:: max(1, len(data) // 4000)]
        ax.scatter(sub[:, dims[0]], sub[:, dims[1]], s=2, c="0.7")
        mu = comparison[init]["motion_means"]
        cov = comparison[init]["motion_covariances"]
        for k in range(len(mu)):
            c = cov[k][np.ix_(dims, dims)]
            w, v = np.linalg.eigh(c)
            ang = np.degrees(np.arctan2(v[1, 1], v[0, 1]))
            ax.add_patch(Ellipse(mu[k, list(dims)], 2 * np.sqrt(w[1]), 2 * np.sqrt(w[0]), angle=ang, fill=False, color="C3"))
        ax.set_title(f"({'a' if init == 'random' else 'b'}) {init} initialization, {len(mu)} states")
        ax.set_xlabel(labels[0])
        ax.set_ylabel(labels[1])
    fig.tight_layout()
    return fig


def states_curve_figure(curves: dict) -> Figure:
    """The paper's Fig. 9: validation CCA_m and LLR versus the number of states, per model kind.
    curves: kind -> {number of states: {"cca_m", "llr"}}."""
    fig = Figure(figsize=(9, 3.6))
    for i, kind in enumerate(sorted(curves)):
        ax = fig.add_subplot(1, len(curves), i + 1)
        ns = sorted(int(n) for n in curves[kind])
        ax.plot(ns, [curves[kind][n]["cca_m"] for n in ns], "o-", color="C0")
        ax.set_xlabel("#states" + (" per constraint" if kind == "cdbn" else ""))
        ax.set_ylabel("CCA_m", color="C0")
        ax2 = ax.twinx()
        ax2.plot(ns, [curves[kind][n]["llr"] for n in ns], "s--", color="C1")
        ax2.set_ylabel("LLR", color="C1")
        ax.set_title(kind)
    fig.tight_layout()
    return fig


def trajectories_figure(fps: float, original: np.ndarray, synthesized: dict, constraints: np.ndarray,
                        names: tuple) -> Figure:
    """Head pitch, yaw and roll (degrees) of one turn: the original and each synthesized trajectory
    (name -> (T, 3)), with the frames of each constraint (codes >= 1 of ``names``) shaded."""
    fig = Figure(figsize=(10, 5))
    t = np.arange(len(original)) / fps
    for i, lab in enumerate(("pitch", "yaw", "roll")):
        ax = fig.add_subplot(3, 1, i + 1)
        ax.plot(t, original[:, i], color="k", lw=1.2, label="original")
        for j, (k, v) in enumerate(synthesized.items()):
            ax.plot(t, v[:, i], lw=1, color=f"C{j}", label=k)
        for code in range(1, len(names)):
            m = constraints == code
            if m.any():
                ax.fill_between(t, 0, 1, where=m, transform=ax.get_xaxis_transform(), alpha=0.15,
                                color=f"C{code + 3}", label=names[code] if i == 0 else None)
        ax.set_ylabel(f"{lab} (deg)")
    fig.axes[0].legend(loc="upper right", fontsize=7, ncol=5)
    fig.axes[-1].set_xlabel("time (s)")
    fig.tight_layout()
    return fig
