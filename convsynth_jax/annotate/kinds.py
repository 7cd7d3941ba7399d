"""The registry of audio labels, constraint kinds and co-occurrence hypotheses: what the annotation
labels, what the search constrains, and which motion each hypothesis pairs with, as data.

*Labels* are the per-frame audio codes of one channel (own or partner speech): ``idle`` = 0, ``PC``
(phonemic clause) = 1, ``LR`` (listener response) = 2, ``HP`` (hesitation pause) = 3. A frame holds
one label per channel (docs/decisions.md, "One audio label per frame and channel").

*Constraint kinds* are what a search window asks of a path and what the checker verifies: a label on
a channel plus how it is matched. The built-in kinds, in report order:

======  ========  =====  ====  ========  ===============  ==========
name    channel   label  peak  retimed   weight           switch
======  ========  =====  ====  ========  ===============  ==========
PC      own       PC     yes   yes       ``weight_pc``    (always)
LR      own       LR     no    yes       ``weight_lr``    ``use_lr``
PH      partner   HP     no    no        ``weight_hp``    ``use_hp``
idle    own       idle   no    no        ``weight_idle``  (always)
======  ========  =====  ====  ========  ===============  ==========

``idle`` is the rule that the own label stays idle outside every own input segment; the others are
*segment kinds*: each input segment of their label on their channel is one constraint. The weight
(best effort, ``search/relax.py``) and the switch are names of :class:`~convsynth_jax.search.params.SearchParams`
fields, read from the search's parameters (a kind may give a number instead of a field name, and no
switch: it is then always on). Partner kinds have no F0 peak and are not retimed (the search's
encoding has no partner peak; the warp moves the own character's segments only).

*Hypotheses* (paper Table 1): an audio label on a channel and the motion kinds that co-occur with it,
plus the generator's planting probability of the synthetic corpus.

Adding a kind: :func:`register_kind` (and an annotation that produces segments of its label);
constraints, checker, relaxation, retiming and the playback diagnostics read this registry.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from ..errors import ConfigError, LabelError

IDLE, PC, LR, HP = 0, 1, 2, 3
CHANNELS = ("own", "partner")
MAX_LABEL_CODE = 15     # the packed beam search keeps a label in 4 bits (search/graph_arrays.py)

# label name -> per-frame code (registered kinds may add labels)
AUDIO_LABELS = {"idle": IDLE, "PC": PC, "LR": LR, "HP": HP}
AUDIO_LABEL_NAMES = {v: k for k, v in AUDIO_LABELS.items()}


@dataclass(frozen=True)
class ConstraintKind:
    """One kind of audio constraint (module docstring). ``name`` names it in constraint keys, reports
    and the checker's details; ``label`` is the annotation's segment kind (and per-frame label) it
    constrains on ``channel``; ``weight``: a SearchParams field name or a number; ``switch``: a
    SearchParams bool field that turns the kind on (None: always on); the condition of
    ``conf/system/motion_graph.yaml`` that leaves the kind out is ``no_`` + the switch without its
    ``use_`` (:attr:`condition_off`); ``description``: what its segments are, in words (plural)."""

    name: str
    label: str
    channel: str = "own"
    has_peak: bool = False
    retimable: bool = False
    weight: str | float = 1.0
    switch: str | None = None
    description: str = ""

    @property
    def code(self) -> int:
        return AUDIO_LABELS[self.label]

    @property
    def condition_off(self) -> str | None:
        """The ablation condition that leaves the kind out (``use_lr`` -> ``no_lr``; None: no switch)."""
        return None if self.switch is None else "no_" + self.switch.removeprefix("use_")

    def weight_of(self, params) -> float:
        """The best-effort weight under ``params`` (SearchParams)."""
        if not isinstance(self.weight, str):
            return float(self.weight)
        if not hasattr(params, self.weight):
            raise ConfigError(f"constraint kind {self.name!r}: its weight names search.{self.weight}, "
                              "which the search parameters do not have")
        return float(getattr(params, self.weight))

    def enabled(self, switches) -> bool:
        """Is the kind on? ``switches``: SearchParams (or any object with the switch as an attribute)
        or a mapping switch -> bool; a switch it does not name is on."""
        if self.switch is None:
            return True
        if isinstance(switches, Mapping):
            return bool(switches.get(self.switch, True))
        return bool(getattr(switches, self.switch, True))


@dataclass(frozen=True)
class Hypothesis:
    """A co-occurrence hypothesis (paper Table 1): segments of ``label`` on ``channel`` and the motion
    kinds of the character's own body that co-occur with them; ``planting``: the synthetic generator's
    probability parameter (``data/synthetic``)."""

    name: str
    channel: str
    label: str
    motions: tuple
    planting: str


IDLE_KIND = ConstraintKind("idle", "idle", "own", weight="weight_idle", description="idle runs")
_KINDS: dict = {}
for _k in (ConstraintKind("PC", "PC", "own", has_peak=True, retimable=True, weight="weight_pc",
                          description="phonemic clauses"),
           ConstraintKind("LR", "LR", "own", retimable=True, weight="weight_lr", switch="use_lr",
                          description="listener responses"),
           ConstraintKind("PH", "HP", "partner", weight="weight_hp", switch="use_hp",
                          description="partner hesitations")):
    _KINDS[_k.name] = _k

MOTION_KINDS = ("LH", "RH", "Nod")
_HYPOTHESES = {h.name: h for h in (
    Hypothesis("PC-LH", "own", "PC", ("LH",), "p_pc_lh"),
    Hypothesis("PC-RH", "own", "PC", ("RH",), "p_pc_rh"),
    Hypothesis("PC-LH/RH", "own", "PC", ("LH", "RH"), "p_pc_either"),
    Hypothesis("LR-Nod", "own", "LR", ("Nod",), "p_lr_nod"),
    Hypothesis("PH-Nod", "partner", "HP", ("Nod",), "p_ph_nod"),
)}
HYPOTHESES = tuple(_HYPOTHESES)


def audio_label_code(name: str) -> int:
    try:
        return AUDIO_LABELS[name]
    except KeyError:
        raise LabelError(f"unknown audio label {name!r}; expected one of {sorted(AUDIO_LABELS)}") from None


def register_kind(kind: ConstraintKind) -> ConstraintKind:
    """Add a constraint kind (and its label, with the next free code, when the label is new). Returns
    it. Errors name the kind: a taken name, an unknown channel, a partner kind with a peak or retiming
    (unsupported), or no label code left."""
    if kind.name in _KINDS or kind.name == IDLE_KIND.name:
        raise ConfigError(f"constraint kind {kind.name!r} is registered already")
    if kind.channel not in CHANNELS:
        raise ConfigError(f"constraint kind {kind.name!r}: channel must be one of {list(CHANNELS)}, "
                          f"got {kind.channel!r}")
    if kind.channel == "partner" and (kind.has_peak or kind.retimable):
        raise ConfigError(f"constraint kind {kind.name!r}: partner kinds can have no peak and cannot be retimed")
    if any(k.label == kind.label and k.channel == kind.channel for k in _KINDS.values()):
        raise ConfigError(f"constraint kind {kind.name!r}: label {kind.label!r} on the {kind.channel} channel "
                          "is constrained by another kind already")
    if kind.label not in AUDIO_LABELS:
        code = max(AUDIO_LABELS.values()) + 1
        if code > MAX_LABEL_CODE:
            raise ConfigError(f"constraint kind {kind.name!r}: no audio label code left (at most {MAX_LABEL_CODE})")
        AUDIO_LABELS[kind.label] = code
        AUDIO_LABEL_NAMES[code] = kind.label
    _KINDS[kind.name] = kind
    return kind


def unregister_kind(name: str) -> None:
    """Remove a registered kind (and its label when no other kind uses it and it is not built in)."""
    kind = _KINDS.pop(name)
    if kind.label not in ("idle", "PC", "LR", "HP") and not any(k.label == kind.label for k in _KINDS.values()):
        AUDIO_LABEL_NAMES.pop(AUDIO_LABELS.pop(kind.label), None)


def segment_kinds(channel: str | None = None) -> tuple:
    """The registered segment kinds (every kind but idle) in registration order, of one channel or all."""
    return tuple(k for k in _KINDS.values() if channel is None or k.channel == channel)


def constraint_kinds() -> tuple:
    """Every constraint kind in report order: the segment kinds, then idle."""
    return segment_kinds() + (IDLE_KIND,)


def constraint_kind(name: str) -> ConstraintKind:
    """The kind named ``name`` (a constraint key's first entry)."""
    if name == IDLE_KIND.name:
        return IDLE_KIND
    try:
        return _KINDS[name]
    except KeyError:
        raise ConfigError(f"unknown constraint kind {name!r}; expected one of "
                          f"{[k.name for k in constraint_kinds()]}") from None


def kind_of_segment(channel: str, label: str) -> ConstraintKind | None:
    """The kind that constrains input segments of ``label`` on ``channel`` (None: unconstrained, e.g.
    an own hesitation)."""
    for k in _KINDS.values():
        if k.channel == channel and k.label == label:
            return k
    return None


def hypotheses() -> tuple:
    """The co-occurrence hypotheses (:class:`Hypothesis`) in table order."""
    return tuple(_HYPOTHESES.values())
