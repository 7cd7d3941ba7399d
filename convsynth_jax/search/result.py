"""The result of a search, and the sentences that explain a failure."""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ..annotate.kinds import constraint_kind, kind_of_segment
from ..errors import ConfigError


@dataclass
class SearchResult:
    success: bool
    path: np.ndarray | None          # (T,) graph state per output frame
    cost: float
    num_synthetic_transitions: int
    constraints_total: int
    constraints_met: int
    failed_frame: int | None = None  # first output frame where every candidate died
    failed_segment: dict | None = None
    seconds: float = 0.0
    method: str = ""
    transition_costs: list | None = None
    synthetic_at: list | None = None  # output frames t whose transition t-1 -> t is synthetic
    failure: str | None = None        # why no path was found (None on success)
    # search.on_failure=best_effort (ours, search/relax.py): the path meets the constraints not relaxed
    best_effort: bool = False
    relaxed: list | None = None       # keys (constraints.constraint_key) of the constraints left out
    claimed: dict | None = None       # key -> met, as the search sees it (relax.claims)
    lookahead_calls: int = 0          # look-ahead calls of the greedy relaxation
    warp: tuple | None = None         # retiming (ours): (output knots, path knots), search/retime.py


def path_stats(graph, path):
    """(total cost, costs of the synthetic transitions, output frames where they arrive) of a path,
    each transition taken along its cheapest edge."""
    total, costs, at = 0.0, [], []
    for i, (a, b) in enumerate(zip(path[:-1], path[1:])):
        tg, c, s = graph.out_edges(int(a))
        k = np.flatnonzero(tg == b)
        if k.size == 0:
            raise ValueError(f"no edge {a} -> {b} in the graph")
        k = k[np.argmin(c[k])]
        total += float(c[k])
        if s[k]:
            costs.append(float(c[k]))
            at.append(i + 1)
    return total, costs, at


def failed_segment_at(constraints, frame):
    if frame is None:
        return None
    for s in constraints.segments:
        if s["start"] - constraints.tol <= frame < s["end"] + constraints.tol:
            return dict(s)
    return {"kind": "frame", "start": int(frame)}


def failure_reason(constraints, frame, method: str) -> str:
    """A sentence naming the constraint (kind, frames) at which every candidate path died."""
    seg = failed_segment_at(constraints, frame) or {}
    mode = "paper" if getattr(constraints, "paper", None) is not None else "labels"
    return (f"{method} search ({mode} matching): no path satisfies the {seg.get('kind', '?')} constraint at "
            f"output frames {seg.get('start')}-{seg.get('end', '?')} (every candidate died at frame {frame})")


# The last sentence of every failure under the paper's rule (``search.on_failure=fail``): what would
# make motion for the window. Per kind of the constraint at which the search died: the condition of
# ``conf/system/motion_graph.yaml`` that leaves that kind out (the registry's ``condition_off``; a kind
# without a switch: only ``none``, no audio constraint).
NEXT_STEP = "To make motion for this window"


def _kind_named(name):
    """The registered kind named ``name``, or constraining the partner label ``name`` (HP), or None."""
    if name is None:
        return None
    try:
        return constraint_kind(name)
    except ConfigError:
        return kind_of_segment("partner", name)


def next_step(params, failed_segment: dict | None = None) -> str | None:
    """The sentence ending a failure under the paper's rule (None under best effort, which has made
    what motion there is): ``preset=quality`` (best effort), or leaving out the failed constraint's kind."""
    if str(getattr(params, "on_failure", "fail")) == "best_effort":
        return None
    kind = (failed_segment or {}).get("kind")
    k = _kind_named(kind)
    if k is not None and k.condition_off is not None:
        drop = f"leaving the {k.description} out (condition {k.condition_off}) may solve it under the paper's rule"
    else:
        drop = ("under the paper's rule only the condition none (no audio constraint) leaves "
                f"{'the ' + kind + ' constraints' if k is not None else 'this constraint'} out")
    return (f"{NEXT_STEP}: preset=quality (ours: search.on_failure=best_effort keeps the path that meets the most "
            f"constraints, with retiming) makes motion for it; {drop}.")


def with_next_step(res: SearchResult, params) -> SearchResult:
    """``res`` with :func:`next_step` ending its failure text (once; unchanged on success)."""
    if res.success or not res.failure or NEXT_STEP in res.failure:
        return res
    hint = next_step(params, res.failed_segment)
    if hint is not None:
        res.failure = f"{res.failure}. {hint}"
    return res


def explained(search):
    """A search function (graph, constraints, params, seed=..., **kw) -> SearchResult whose failures
    end with :func:`next_step`: the form every caller of a registered search gets
    (``synth/pipeline.py: SEARCHES``)."""
    @functools.wraps(search)
    def run(graph, constraints, params, *args, **kwargs):
        return with_next_step(search(graph, constraints, params, *args, **kwargs), params)
    run.unexplained = search
    return run
