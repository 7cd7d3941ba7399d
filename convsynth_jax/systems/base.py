"""The speech-driven synthesis-system interface shared by every system of the framework.

A *system* turns held-out conversation audio into motion for one character. The leave-one-out
evaluation (``convsynth_jax.evaluation.loo``), the main job, the summaries and the notebooks only
talk to this interface, so a new system is one module plus one ``conf/system/<name>.yaml``:

1. ``fit(clips, character, condition, cache_dir)`` learns a model from the training sessions of a
   fold (the motion graph builds a graph; the CDBN trains a DBN). ``clips`` are the character's
   :class:`~convsynth_jax.annotate.pipeline.ParticipantAnnotation` records (motion, own and partner
   audio segments and per-frame labels). ``fit_key(condition)`` says which conditions share one
   model (the motion graph: all of them; a system whose training depends on the condition returns
   the condition), so a fold fits each distinct model once.
2. ``synthesize(model, window, condition)`` produces a :class:`WindowResult` for one
   :class:`WindowInput` (audio segments, per-frame labels and samples of both channels over the
   window, plus a seed derived by :func:`convsynth_jax.seeding.derive_seed`).

Ablation conditions are named in the system's config (``system.conditions``: name -> options). A
system's ``condition_type`` is the frozen dataclass of one condition's options: each condition is
converted to it when the config is converted (:class:`SystemParams`), so a mistyped value
(``system.conditions.no_lr.use_lr=nope``) or an unknown key is a ConfigError naming the key before
any work, never a truthy string at synthesis time. The evaluation checks the requested condition
against them and passes its options through (:meth:`SynthesisSystem.condition_options`: the options
the condition sets).
Results carry generic fields only; anything system-specific goes into ``diagnostics``, or comes
from two optional hooks the evaluation calls on every synthesized window (default: nothing):
``window_diagnostics(model, window, result)`` adds system-specific columns (the motion graph's
independent constraint checker), and ``source_positions(model, clip)`` gives the joint positions of
a training clip the output was played back from (``WindowResult.source_clip``), for the seam
content ratio. ``motion_graph(model)`` gives the graph a model searches (the tasks report its size
and save it; default: none). ``options_type``: the dataclass of the system's ``options`` (its
defaults are the only ones; an unknown key is a ConfigError naming it).
"""
from __future__ import annotations

import abc
import importlib
from dataclasses import dataclass, field, fields, is_dataclass
from typing import TYPE_CHECKING, Any, Dict, Mapping, Sequence

import numpy as np

from ..errors import ConfigError
from ..schema import build_params

if TYPE_CHECKING:   # annotations only: importing the configuration does not import pandas
    import pandas as pd


@dataclass(frozen=True)
class SystemParams:
    """``conf/system/<name>.yaml``.

    name: registry name; factory: ``"package.module:Class"`` building the system from
    ``(params, system_params)``; conditions: ablation condition name -> options (system-specific
    switches, e.g. ``{use_lr: false}``); options: further system-specific settings.
    """

    name: str
    factory: str
    conditions: Dict[str, Any]
    options: Dict[str, Any] = field(default_factory=dict)

    def __post_init__(self):
        """Each condition converted to its system's ``condition_type`` (a ConfigError naming the key of a
        mistyped value or an unknown key); a system without one (or a factory that cannot be loaded,
        which ``make_system`` reports) keeps plain mappings."""
        try:
            ctype = getattr(load_factory(self.factory), "condition_type", None)
        except ConfigError:  # reported by make_system, which needs the factory
            ctype = None
        conditions = {}
        for cond, opts in dict(self.conditions or {}).items():
            where = f"system.conditions.{cond}"
            if ctype is None:
                if opts is not None and not isinstance(opts, Mapping):
                    raise ConfigError(f"{where}: expected a mapping of options, got {type(opts).__name__} {opts!r}")
                conditions[str(cond)] = dict(opts or {})
            else:
                conditions[str(cond)] = build_params(ctype, opts, where)
        object.__setattr__(self, "conditions", conditions)


@dataclass(frozen=True)
class WindowInput:
    """One held-out window of one character: everything a speech-driven system may look at.

    Segment times are seconds relative to the window start (segments crossing an edge keep their
    true times). ``own_frames``/``partner_frames`` are per-frame labels over the window
    (``num_frames`` frames at ``fps``); ``own_audio``/``partner_audio`` are the window's samples
    (None when the corpus has no audio). ``chair_index`` places the character in the scene (0 or 1).
    """

    session: str
    role: str
    character: str
    start_frame: int
    num_frames: int
    fps: float
    own_segments: pd.DataFrame
    partner_segments: pd.DataFrame
    own_frames: Any = None
    partner_frames: Any = None
    own_audio: Any = None
    partner_audio: Any = None
    chair_index: int = 0
    seed: int = 0


@dataclass
class WindowResult:
    """What a system returns for one window.

    motion: a :class:`~convsynth_jax.skeleton.Motion` of ``num_frames`` frames (None on failure);
    seconds: synthesis wall-clock time; constraints_total/met: the audio constraints the system
    tried to satisfy and how many it met (0/0 for systems without constraints); source_clip /
    source_frame: per-frame provenance (the training clip and frame each output frame comes from)
    where the system has one, else None; failure: why no motion was produced; diagnostics:
    system-specific scalars (e.g. path cost, synthetic transitions), written as ``diag_<key>`` columns.
    """

    success: bool
    motion: Any = None
    seconds: float = 0.0
    constraints_total: int = 0
    constraints_met: int = 0
    failure: str | None = None
    source_clip: Sequence[str] | None = None
    source_frame: np.ndarray | None = None
    diagnostics: dict = field(default_factory=dict)
    synthetic_at: Sequence[int] | None = None  # output frames where a synthetic transition arrives
    blend_frames: int = 0                      # frames each synthetic transition is blended over


class SynthesisSystem(abc.ABC):
    """Base class of a speech-driven synthesis system (see the module docstring)."""

    #: hand motion produced? (False: hand co-occurrence hypotheses are reported as not applicable)
    produces_hands: bool = True
    #: does synthesize() read WindowInput.own_audio / partner_audio? (they are loaded only then);
    #: training clips carry ``audio_path``/``audio_channel`` for systems that need samples in fit()
    needs_audio: bool = False

    #: the names of its two timed procedures in Table 3 (the leave-one-out rows carry them)
    fit_procedure: str = "fit"
    synthesis_procedure: str = "synthesis"
    #: the frozen dataclass of ``system.options`` (conf/system/<name>.yaml): its defaults are the only
    #: ones, a key it lacks is a ConfigError naming it; None: the options stay a plain mapping
    options_type: type | None = None
    #: the frozen dataclass of one ablation condition's options (``system.conditions.<name>``): its
    #: fields are the only keys, typed; a field left None keeps the system's configured value. None:
    #: conditions stay plain mappings
    condition_type: type | None = None
    #: whether :meth:`synthesize_audio` makes one character's motion for a whole conversation of any
    #: length from the two speakers' audio alone (``task=converse`` calls it instead of chaining
    #: searched windows)
    converses_from_audio: bool = False

    def __init__(self, params, system: SystemParams):
        self.params = params
        self.system = system
        opts = dict(system.options or {})
        self.options = opts if self.options_type is None else \
            build_params(self.options_type, opts, f"system.options ({system.name})")

    @property
    def name(self) -> str:
        return self.system.name

    @property
    def conditions(self) -> Mapping[str, dict]:
        return self.system.conditions

    def condition(self, condition: str):
        """The typed options of ``condition`` (a ``condition_type`` instance, or a mapping for a system
        without one); a ConfigError listing the system's conditions when it has no such condition."""
        if condition not in self.system.conditions:
            raise ConfigError(f"system {self.name!r} has no condition {condition!r}; "
                              f"its conditions are {sorted(self.system.conditions)} (conf/system/{self.name}.yaml)")
        return self.system.conditions[condition]

    def condition_options(self, condition: str) -> dict:
        """The options ``condition`` sets: name -> value (the fields it leaves None are left out)."""
        opts = self.condition(condition)
        if is_dataclass(opts):
            return {f.name: getattr(opts, f.name) for f in fields(opts) if getattr(opts, f.name) is not None}
        return dict(opts or {})

    def fit_key(self, condition: str) -> Any:
        """Conditions with equal keys share one fitted model (default: one model for all)."""
        return None

    @abc.abstractmethod
    def fit(self, clips: Sequence, character: str, condition: str, cache_dir=None) -> Any:
        """A model of ``character`` from its training ``clips`` (ParticipantAnnotation records)."""

    @abc.abstractmethod
    def synthesize(self, model: Any, window: WindowInput, condition: str) -> WindowResult:
        """Motion for one window of held-out audio."""

    def synthesize_audio(self, model: Any, own_audio, partner_audio, num_frames: int, fps: float, seed: int,
                         chair_index: int = 0, name: str = ""):
        """A Motion of ``num_frames`` frames at ``fps`` for ``model``'s character from its own audio and the
        partner's (``io.Audio`` each), at chair ``chair_index``: only systems with ``converses_from_audio``."""
        raise ConfigError(f"system {self.name!r} makes no conversation from audio alone (converses_from_audio is false)")

    def prepare(self, models: Mapping[str, Any]) -> None:
        """Called with the fitted models of one conversation (character -> model) before its windows
        are synthesized, e.g. to let their kernels share one compiled program; default: nothing."""

    def window_diagnostics(self, model: Any, window: WindowInput, result: WindowResult) -> Dict[str, Any]:
        """System-specific columns of one successfully synthesized window (e.g. an independent
        re-check of its constraints), written into the leave-one-out row as given; default: none."""
        return {}

    def source_positions(self, model: Any, clip: str) -> np.ndarray | None:
        """(F, J, 3) global joint positions of the whole training clip ``clip`` named in
        ``WindowResult.source_clip`` (for the seam content ratio); default: None (no provenance)."""
        return None

    def fit_seconds(self, model: Any) -> float:
        """Construction / training time of ``model`` (for Table 3), NaN if unknown."""
        return float(getattr(model, "seconds", float("nan")))

    def motion_graph(self, model: Any):
        """The motion graph (``graph.MotionGraph``) ``model`` searches, for what the tasks report and save
        of a graph (its size, threshold, the graph file, the paper's graph statistics); default: None
        (the model has no graph)."""
        return None


def load_factory(spec: str):
    """``"package.module:Attr"`` -> the attribute (a SynthesisSystem subclass or factory)."""
    mod, _, attr = spec.partition(":")
    if not mod or not attr:
        raise ConfigError(f"system.factory must look like 'package.module:Class', got {spec!r}")
    try:
        return getattr(importlib.import_module(mod), attr)
    except (ImportError, AttributeError) as e:
        raise ConfigError(f"cannot load system factory {spec!r}: {e}") from None


def make_system(params, system: SystemParams) -> SynthesisSystem:
    """Build the system named by ``system`` (its ``factory``) with the typed ``params``."""
    sys_obj = load_factory(system.factory)(params, system)
    if not isinstance(sys_obj, SynthesisSystem):
        raise ConfigError(f"system factory {system.factory!r} did not return a SynthesisSystem")
    return sys_obj
