"""Parameters of the audio-constrained search (paper Section 7); ``conf/search``."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import List, Optional


@dataclass(frozen=True)
class SearchParams:
    method: str = "beam"          # beam (JAX, ours) | dfs (the paper's depth-first stochastic greedy search)
    # paper: each input segment (PC, LR, partner HP) is matched by ONE whole source segment of its kind
    # whose start, F0 peak (PC) and end lie within ``tolerance`` of the input's, short segments
    # included; labels (ours, relaxed): the path's per-frame labels match, see search/constraints.py
    matching: str = "paper"
    tolerance: float = 0.1        # seconds, for start/peak/end matching
    use_constraints: bool = True  # False: no audio constraint at all (graph quality only)
    use_lr: bool = True           # listener-response constraints
    use_hp: bool = True           # partner-hesitation constraints
    beam_size: int = 256          # beam: paths kept per frame
    max_degree: int = 64          # out-edges per state considered (cheapest first)
    max_candidates: int = 2048    # beam: candidate slots per frame (overflow drops the most expensive ranks)
    temperature: float = 0.05     # sampling temperature, relative to the median synthetic edge cost
    # beam: retry hotter (more diverse, more synthetic transitions) when no path survives
    retry_temperatures: List[float] = field(default_factory=lambda: [1.0])
    # beam: then retry once more at every temperature with this wider beam and candidate budget (0: off);
    # paper matching often needs it: a path must be positioned to enter one of the few source clauses
    # of the right length at the right frame
    retry_beam_size: int = 2048
    retry_max_candidates: int = 16384
    # ours: keep only candidates that can still complete the window (exact backward reachability over
    # (state, flags), search/feasible.py): the beam then solves every solvable window at its first
    # attempt, and an unsolvable one is known at once (no retries); the DFS prunes the same way
    lookahead: bool = True
    # ours: how the look-ahead is computed (search/feasible.py, docs/scale.md), the same bits either way:
    # "changed" (frame to frame, only the states whose bits changed and their in-edges), "dense" (every
    # state every frame), "auto" (changed on graphs of 131,072 padded states or more, else dense)
    lookahead_pass: str = "auto"
    n_start: int = 50             # DFS: random start states (our bound; the paper gives none)
    n_save: int = 200             # DFS: candidates kept per segment (paper: 200)
    max_paths_per_start: int = 20  # DFS: our bound
    max_expansions: int = 200000  # DFS: our bound per segment, shared among start states
    time_budget: Optional[float] = None  # DFS: optional wall-clock bound in seconds (None: expansions only)
    # when no path meets every constraint: "fail" (the paper) or "best_effort" (ours: the path meeting
    # the most constraints, weighted by kind, found by greedy relaxation; search/relax.py, docs/search.md)
    on_failure: str = "fail"
    # best_effort: weight of each constraint kind (own clause PC, own listener response LR, partner
    # hesitation PH, own idle run); heavier kinds are kept first
    weight_pc: float = 4.0
    weight_lr: float = 2.0
    weight_hp: float = 2.0
    weight_idle: float = 1.0
    # ours (the paper's future work): a source clause may match an input clause (own PC or LR) whose
    # duration differs by up to this fraction (0: off, the paper; 0.2: +-20%); realization then warps the
    # matched segments' start, F0 peak and end onto the input's (synth/retime.py). matching=paper only
    retime_factor: float = 0.0
    # ours: with retiming, the START of an own clause or response may also lie off the input's by up to
    # tol + floor(start_slack_factor * g), g the input's idle gap before it (frames since the previous own
    # segment's end); the warp moves it onto the input's start and stretches or shrinks the idle gap. A run
    # of the recording that plays one clause, its pause and the next clause can then match two consecutive
    # input clauses whose pause differs from the recording's (docs/search.md). 0: the start keeps tol
    start_slack_factor: float = 0.0
