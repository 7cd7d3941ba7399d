"""The design of a forced-choice study (paper Section 8.1): pairs of conditions, segments, which
side shows which condition, attention checks, and each participant's trials.

The paper: 20 segments x 4 pairs x 10 repetitions, two techniques side by side "randomly assigned
to the left or right", 20 rounds per participant, a forced choice after each. Ours (named here so
they are not mistaken for the paper's): sides are balanced per pair (half of each pair's segments
show condition A on the left, the rest on the right, which half chosen by the seed); attention-check
trials (ground truth beside the same ground truth frozen at its first frame) are mixed into every
participant's trials; trials are assigned least-assigned-first, so stimuli reach their repetitions
evenly as participants arrive.

Everything here is a pure function of its inputs and a seed (NumPy ``Generator``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError

GROUND_TRUTH = "ground_truth"      # the held-out recording's own motion (the paper's "motion capture")
FROZEN = "frozen"                  # attention checks: the ground truth held at its first frame


@dataclass(frozen=True)
class Pair:
    """One comparison: condition ``a`` against ``b`` (``ground_truth`` or a system condition);
    ``label_a``/``label_b`` name them in Figure 6."""

    name: str
    a: str
    b: str
    label_a: str
    label_b: str


# The paper's four comparisons (Section 8.1, Figure 6)
PAPER_PAIRS = (
    Pair("gt_vs_all", GROUND_TRUTH, "all", "Motion capture", "All constraints"),
    Pair("all_vs_no_lr", "all", "no_lr", "All constraints", "Without LR"),
    Pair("all_vs_no_hp", "all", "no_hp", "All constraints", "Without HP"),
    Pair("all_vs_none", "all", "none", "All constraints", "No constraints"),
)


def pairs_from_config(entries) -> tuple[Pair, ...]:
    """Pairs from config entries (mappings with name, a, b and optional label_a, label_b)."""
    out = []
    for i, e in enumerate(entries):
        e = dict(e)
        missing = {"name", "a", "b"} - set(e)
        if missing:
            raise ConfigError(f"study pair {i} lacks {sorted(missing)}", where=f"task.pairs[{i}]")
        if e["a"] == e["b"]:
            raise ConfigError(f"study pair {e['name']!r} compares {e['a']!r} with itself", where=f"task.pairs[{i}]")
        out.append(Pair(str(e["name"]), str(e["a"]), str(e["b"]), str(e.get("label_a") or e["a"]),
                        str(e.get("label_b") or e["b"])))
    if len({p.name for p in out}) != len(out):
        raise ConfigError("study pair names must be distinct", where="task.pairs")
    if not out:
        raise ConfigError("a study needs at least one pair", where="task.pairs")
    return tuple(out)


def conditions_needed(pairs) -> list[str]:
    """The system conditions the pairs compare (ground truth excluded), in first-use order."""
    seen = []
    for p in pairs:
        for c in (p.a, p.b):
            if c != GROUND_TRUTH and c not in seen:
                seen.append(c)
    return seen


def plan_stimuli(segments: list[dict], pairs, attention: int, seed: int) -> list[dict]:
    """One stimulus per (segment, pair), plus ``attention`` attention checks.

    segments: dicts with at least ``segment`` (index); copied into each stimulus. Per pair, a
    seeded permutation of the segments puts condition ``a`` on the left for the first half
    (``ceil(n/2)`` in even-numbered pairs, ``floor(n/2)`` in odd ones, so sides balance over pairs
    too) and on the right for the rest. Attention checks take segments in turn; the
    moving side is random. Stimulus ids: ``s000``.. in order; each has kind ("pair" or
    "attention"), pair, left, right, condition_a/b and expected (attention: the side to choose)."""
    rng = np.random.default_rng([int(seed), 7])
    out = []
    n = len(segments)
    for j, p in enumerate(pairs):
        order = rng.permutation(n)
        a_left = np.zeros(n, bool)
        a_left[order[: (n + 1 - j % 2) // 2]] = True       # odd n: pairs alternate which side gets the extra one
        for i, seg in enumerate(segments):
            left, right = (p.a, p.b) if a_left[i] else (p.b, p.a)
            out.append({**seg, "kind": "pair", "pair": p.name, "condition_a": p.a, "condition_b": p.b,
                        "label_a": p.label_a, "label_b": p.label_b, "left": left, "right": right, "expected": None})
    for k in range(attention):
        seg = segments[k % n]
        moving_left = bool(rng.integers(2))
        left, right = (GROUND_TRUTH, FROZEN) if moving_left else (FROZEN, GROUND_TRUTH)
        out.append({**seg, "kind": "attention", "pair": "attention", "condition_a": GROUND_TRUTH, "condition_b": FROZEN,
                    "label_a": "Moving", "label_b": "Frozen", "left": left, "right": right,
                    "expected": "left" if moving_left else "right"})
    for i, s in enumerate(out):
        s["id"] = f"s{i:03d}"
    return out


def choose_trials(stimuli: list[dict], counts: dict, trials: int, attention: int, seed: int, participant_index: int) -> list[str]:
    """One participant's trial order: ``trials`` distinct pair stimuli, least assigned first
    (``counts``: stimulus id -> participants assigned so far; ties broken at random), shuffled, with
    ``attention`` attention checks inserted at random places after the first trial."""
    rng = np.random.default_rng([int(seed), 11, int(participant_index)])
    regular = [s["id"] for s in stimuli if s["kind"] == "pair"]
    checks = [s["id"] for s in stimuli if s["kind"] == "attention"]
    if trials > len(regular):
        raise ConfigError(f"{trials} trials per participant but only {len(regular)} stimuli", where="task.trials_per_participant")
    tie = rng.random(len(regular))
    order = sorted(range(len(regular)), key=lambda i: (counts.get(regular[i], 0), tie[i]))
    chosen = [regular[i] for i in order[:trials]]
    rng.shuffle(chosen)
    if checks and attention:
        picks = rng.choice(len(checks), size=min(attention, len(checks)), replace=False)
        for c in picks:
            pos = int(rng.integers(1, len(chosen) + 1)) if chosen else 0
            chosen.insert(pos, checks[int(c)])
    return chosen


def participants_needed(stimuli: list[dict], repetitions: int, trials: int) -> int:
    """Participants for every pair stimulus to reach ``repetitions`` answers (least-assigned-first)."""
    n = sum(s["kind"] == "pair" for s in stimuli)
    return int(np.ceil(n * repetitions / max(trials, 1)))
