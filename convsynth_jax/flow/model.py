"""Conditional flow matching (Lipman et al. 2023; the rectified-flow / OT path of Liu et al. 2023) for
co-speech motion, in JAX with flax and optax.

Objective: x1 a training window of motion features (z-normalised), x0 ~ N(0, I), t ~ U(0, 1),
x_t = (1 - t) x0 + t x1; the network v(x_t, t, c) regresses the path's velocity x1 - x0 under the
mean squared error. Sampling integrates dx/dt = v from t = 0 to 1 (Euler or midpoint, ``sample_steps``).

Network (small enough for a CPU): a 1-D temporal convolution stack over the window. Input per frame:
x_t, the audio condition c (own and partner channel features), a motion prefix and its mask; a
sinusoidal embedding of t modulates every block (FiLM). Blocks: LayerNorm, dilated convolution
(dilations 1, 2, 4, 8, ...), FiLM, GELU, 1x1 convolution, residual.

Any length: windows of ``window_frames`` overlapping by ``prefix_frames``; each window after the first
is conditioned on the previous output's last ``prefix_frames`` frames (trained with probability
``prefix_probability``) and those frames are also imposed on the path at every step (inpainting:
(1 - t) x0 + t prefix), so a window starts exactly where the previous one ends.

Deterministic under a seed: training draws its batches, times and noise from ``jax.random`` keys
derived from ``seed``; sampling from the caller's seed.
"""
from __future__ import annotations

import hashlib
import logging
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ..errors import ConfigError

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class FlowParams:
    """The model, its training and its sampler (``system.options`` of ``system=flow_matching``)."""

    fps: float = 15.0                # the model's frame rate (motion and audio features resampled to it)
    window_frames: int = 48          # frames per training / sampling window (3.2 s at 15 fps)
    prefix_frames: int = 6           # overlap of consecutive sampling windows (the continuity prefix)
    prefix_probability: float = 0.7  # training windows that see their first prefix_frames as a prefix
    width: int = 96                  # channels of the convolution stack
    blocks: int = 6                  # residual blocks (dilations 1, 2, 4, 8, then again)
    kernel_size: int = 3
    pca_variance: float = 0.995      # the motion's principal components kept (share of its variance)
    pca_max_components: int = 48
    time_embedding: int = 32
    train_steps: int = 1600          # 800 (the earlier default) leaves the model undertrained: docs/flow_matching.md
    batch_size: int = 32
    learning_rate: float = 2e-3      # Adam, cosine decay to 10% over train_steps
    ema_decay: float = 0.0           # ours: sample with an exponential moving average of the weights (debiased); 0: the last weights
    log_every: int = 100             # steps per scanned chunk (one loss-curve point each)
    sample_steps: int = 12
    sampler: str = "midpoint"        # euler | midpoint
    smooth_frames: float = 0.0       # Gaussian smoothing (SD in model frames) of the sampled features; 0: none
    detail_noise: bool = True        # add the recordings' frame-level detail (white, per feature; see the system)
    prediction: str = "data"         # the network predicts: data (x1; velocity (x1_hat - x_t) / (1 - t)) | velocity
    difference_weight: float = 1.0   # data prediction: weight of the frame-to-frame differences' error
    partner_audio: bool = True       # condition on the partner's channel too
    seed: int = 0

    def __post_init__(self):
        if self.prediction not in ("data", "velocity"):
            raise ConfigError(f"flow_matching: prediction must be 'data' or 'velocity', got {self.prediction!r} "
                              "(system.options.prediction)")
        if self.sampler not in ("euler", "midpoint"):
            raise ConfigError(f"flow_matching: sampler must be 'euler' or 'midpoint', got {self.sampler!r} "
                              "(system.options.sampler)")
        if not 0 <= self.prefix_frames < self.window_frames:
            raise ConfigError(f"flow_matching: need 0 <= prefix_frames < window_frames, got {self.prefix_frames}, "
                              f"{self.window_frames} (system.options)")
        if min(self.width, self.blocks, self.train_steps, self.batch_size, self.sample_steps, self.log_every) < 1:
            raise ConfigError("flow_matching: width, blocks, train_steps, batch_size, sample_steps and log_every "
                              "must be positive (system.options)")
        if not 0.0 <= self.ema_decay < 1.0:
            raise ConfigError(f"flow_matching: ema_decay must be in [0, 1), got {self.ema_decay} (system.options.ema_decay)")
        if self.fps <= 0:
            raise ConfigError(f"flow_matching: fps must be positive, got {self.fps} (system.options.fps)")


SAMPLING_ONLY = ("sample_steps", "sampler", "smooth_frames", "detail_noise")   # options that leave the trained model unchanged


def _taps(h, k: int, dilation: int):
    """(B, T, C) -> (B, T, k C): each frame with its k - 1 neighbours ``dilation`` frames apart (zeros
    past the ends), so a dilated convolution is one dense layer (faster on a CPU than XLA's convolution)."""
    import jax.numpy as jnp

    half = (k - 1) // 2
    T = h.shape[1]
    pad = jnp.pad(h, ((0, 0), (half * dilation, half * dilation), (0, 0)))
    return jnp.concatenate([pad[:, i * dilation:i * dilation + T] for i in range(k)], axis=-1)


def _network(dim: int, p: FlowParams):
    import flax.linen as nn
    import jax.numpy as jnp

    width, k = int(p.width), int(p.kernel_size)

    class Block(nn.Module):
        dilation: int

        @nn.compact
        def __call__(self, h, temb):
            y = nn.LayerNorm()(h)
            y = nn.Dense(width)(_taps(y, k, self.dilation))   # a dilated convolution as one matrix product
            scale, shift = jnp.split(nn.Dense(2 * width)(temb), 2, axis=-1)
            y = y * (1.0 + scale[:, None, :]) + shift[:, None, :]
            y = nn.gelu(y)
            y = nn.Dense(width)(y)
            return h + y

    class VelocityField(nn.Module):
        @nn.compact
        def __call__(self, x, t, cond, prefix, mask):
            half = int(p.time_embedding) // 2
            freqs = jnp.exp(-jnp.log(1000.0) * jnp.arange(half) / max(half - 1, 1))
            ang = (t[:, None] * 1000.0) * freqs[None, :]
            temb = jnp.concatenate([jnp.sin(ang), jnp.cos(ang)], axis=-1)
            temb = nn.Dense(width)(nn.silu(nn.Dense(width)(temb)))
            h = nn.Dense(width)(jnp.concatenate([x, cond, prefix * mask, mask], axis=-1))
            for i in range(int(p.blocks)):
                h = Block(2 ** (i % 4))(h, temb)
            return nn.Dense(dim)(nn.LayerNorm()(h))

    return VelocityField()


@dataclass
class FlowModel:
    """A trained velocity field: its flax variables, the architecture's sizes, the loss curve (mean
    loss of every ``log_every`` steps) and the training time, wall and CPU (this process, every
    thread; the original training's when loaded from the cache)."""

    params: FlowParams
    dim: int
    cond_dim: int
    variables: Any
    losses: np.ndarray
    seconds: float
    key: str = ""
    loaded: bool = False
    cpu_seconds: float = float("nan")
    _fns: dict = field(default_factory=dict, repr=False)


def checkpoint_key(arrays: Sequence[np.ndarray], params: FlowParams, extra: str = "") -> str:
    """sha256 over the training arrays, the parameters, ``extra`` (e.g. a corpus fingerprint) and
    the source of this package's model and features (the code version): the one place the cache key
    of a trained model is made."""
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(np.asarray(a, np.float32))
        h.update(str(a.shape).encode())
        h.update(a.tobytes())
    trained = {k: v for k, v in asdict(params).items() if k not in SAMPLING_ONLY}
    h.update(repr(sorted(trained.items())).encode())
    h.update(str(extra).encode())
    here = Path(__file__).resolve().parent
    for name in ("model.py", "features.py"):
        h.update((here / name).read_bytes())
    return h.hexdigest()


def _windows_index(lengths: Sequence[int], window: int) -> np.ndarray:
    """Start rows (into the concatenated sequences) of every window that fits inside one sequence."""
    starts, offset = [], 0
    for n in lengths:
        if n >= window:
            starts.append(offset + np.arange(n - window + 1))
        offset += n
    if not starts:
        raise ConfigError(f"flow_matching: no training sequence has {window} frames (system.options.window_frames)")
    return np.concatenate(starts).astype(np.int32)


def _padded(a: np.ndarray) -> np.ndarray:
    """``a`` with zero rows appended up to a size bucket: steps of a quarter of the largest power of two
    at most ``len(a)`` (at least 64), so the padding adds under a quarter and sizes within a few percent
    of each other mostly share a bucket."""
    n = len(a)
    step = 2 ** max(int(np.floor(np.log2(max(n, 1)))) - 2, 6)
    size = -(-n // step) * step
    return np.concatenate([a, np.zeros((size - n, *a.shape[1:]), a.dtype)]) if size > n else a


def train_flow(motions: Sequence[np.ndarray], conds: Sequence[np.ndarray], params: FlowParams,
               progress: bool = False, label: str = "") -> FlowModel:
    """Train a velocity field on sequences ``motions`` (F_i, D) (normalised features) with their
    conditions ``conds`` (F_i, C), seeded by ``params.seed``."""
    import jax
    import jax.numpy as jnp
    import optax
    from tqdm.auto import tqdm

    p = params
    if len(motions) != len(conds) or not motions:
        raise ConfigError("flow_matching: need one condition sequence per motion sequence, and at least one")
    W, P, B = int(p.window_frames), int(p.prefix_frames), int(p.batch_size)
    lengths = [min(len(m), len(c)) for m, c in zip(motions, conds)]
    # The data are arguments of the jitted training, padded to a size bucket, not constants folded into
    # it: trainings whose arrays fall in one bucket (the folds of a sweep, the characters of a fold)
    # share one compiled program. Windows start only at the real starts (the first n of them).
    X = _padded(np.concatenate([np.asarray(m, np.float32)[:n] for m, n in zip(motions, lengths)]))
    C = _padded(np.concatenate([np.asarray(c, np.float32)[:n] for c, n in zip(conds, lengths)]))
    real_starts = _windows_index(lengths, W)
    decay = float(p.ema_decay)
    data = (jnp.asarray(X), jnp.asarray(C), jnp.asarray(_padded(real_starts)), jnp.asarray(len(real_starts), jnp.int32),
            jnp.asarray(decay, jnp.float32))
    dim, cdim = int(X.shape[1]), int(C.shape[1])
    net = _network(dim, p)
    key = jax.random.PRNGKey(int(p.seed))
    key, k_init = jax.random.split(key)
    variables = net.init(k_init, jnp.zeros((1, W, dim)), jnp.zeros((1,)), jnp.zeros((1, W, cdim)),
                         jnp.zeros((1, W, dim)), jnp.zeros((1, W, 1)))
    sched = optax.cosine_decay_schedule(float(p.learning_rate), int(p.train_steps), alpha=0.1)
    opt = optax.adam(sched)
    opt_state = opt.init(variables)
    frame = jnp.arange(W)[None, :, None]

    def crop(a, s):
        return jax.lax.dynamic_slice_in_dim(a, s, W, axis=0)

    def loss_fn(v, k, data):
        X, C, starts, n_starts, _ = data
        k1, k2, k3, k4 = jax.random.split(k, 4)
        s = starts[jax.random.randint(k1, (B,), 0, n_starts)]    # jax.random.choice(k1, starts[:n_starts], (B,))
        x1 = jax.vmap(lambda s_: crop(X, s_))(s)
        c = jax.vmap(lambda s_: crop(C, s_))(s)
        x0 = jax.random.normal(k2, x1.shape)
        t = jax.random.uniform(k3, (B,))
        use = (jax.random.uniform(k4, (B, 1, 1)) < p.prefix_probability).astype(x1.dtype)
        mask = use * (frame < P).astype(x1.dtype)
        xt = (1.0 - t[:, None, None]) * x0 + t[:, None, None] * x1
        pred = net.apply(v, xt, t, c, x1, mask)
        if p.prediction == "velocity":
            return jnp.mean((pred - (x1 - x0)) ** 2)
        # data prediction (as motion diffusion models do): the error of x1 and of its frame differences
        loss = jnp.mean((pred - x1) ** 2)
        if p.difference_weight > 0 and W > 1:
            loss = loss + p.difference_weight * jnp.mean((jnp.diff(pred, axis=1) - jnp.diff(x1, axis=1)) ** 2)
        return loss

    def step(data, carry, k):
        v, s, ema = carry
        loss, g = jax.value_and_grad(loss_fn)(v, k, data)
        upd, s = opt.update(g, s, v)
        v = optax.apply_updates(v, upd)
        # the moving average of the weights after each step, debiased below (it starts at zero); with
        # decay 0 it is the last weights exactly, and the decay is an argument, so every decay shares
        # one compiled program
        d = data[4]
        ema = jax.tree_util.tree_map(lambda a, b: d * a + (1.0 - d) * b, ema, v)
        return (v, s, ema), loss

    chunk = int(min(p.log_every, p.train_steps))
    run_chunk = jax.jit(lambda carry, keys, data: jax.lax.scan(lambda c, k: step(data, c, k), carry, keys))
    n_chunks = -(-int(p.train_steps) // chunk)
    losses = []
    t0, c0 = time.perf_counter(), time.process_time()
    carry = (variables, opt_state, jax.tree_util.tree_map(jnp.zeros_like, variables))
    with tqdm(total=n_chunks * chunk, desc=f"flow matching {label}".strip(), disable=not progress, leave=False) as bar:
        for i in range(n_chunks):
            keys = jax.random.split(jax.random.fold_in(key, i), chunk)
            carry, ls = run_chunk(carry, keys, data)
            losses.append(float(jnp.mean(ls)))
            bar.update(chunk)
            bar.set_postfix(loss=f"{losses[-1]:.4f}")
            log.debug("flow matching %s: steps %d, loss %.4f", label, (i + 1) * chunk, losses[-1])
    seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    log.info("flow matching %s: %d steps in %.1f s (%.1f s CPU), loss %.4f -> %.4f", label, n_chunks * chunk, seconds,
             cpu, losses[0], losses[-1])
    weights = carry[0]
    if decay > 0:
        debias = np.float32(1.0 - decay ** (n_chunks * chunk))    # the steps taken
        weights = jax.tree_util.tree_map(lambda a: a / debias, carry[2])
    return FlowModel(p, dim, cdim, jax.device_get(weights), np.asarray(losses), seconds, cpu_seconds=cpu)


def _sampler(model: FlowModel):
    """The jitted sampler of one window: (variables, cond (1, W, C), prefix (1, W, D), mask (1, W, 1),
    key) -> (1, W, D)."""
    if "sample" in model._fns:
        return model._fns["sample"]
    import jax
    import jax.numpy as jnp

    p = model.params
    net = _network(model.dim, p)
    n = int(p.sample_steps)
    dt = 1.0 / n

    def sample(v, cond, prefix, mask, key):
        x0 = jax.random.normal(key, prefix.shape)

        def known(x, t):
            return mask * ((1.0 - t) * x0 + t * prefix) + (1.0 - mask) * x

        def vel(x, t):
            xk = known(x, t)
            out = net.apply(v, xk, jnp.full((x.shape[0],), t), cond, prefix, mask)
            if p.prediction == "velocity":
                return out
            return (out - xk) / jnp.maximum(1.0 - t, 1e-3)

        def body(i, x):
            t = i * dt
            if p.sampler == "euler":
                return x + dt * vel(x, t)
            xm = x + 0.5 * dt * vel(x, t)
            return x + dt * vel(xm, t + 0.5 * dt)

        x = jax.lax.fori_loop(0, n, body, x0)
        return known(x, 1.0)

    model._fns["sample"] = jax.jit(sample)
    return model._fns["sample"]


def sample_batch(model: FlowModel, cond: np.ndarray, seed: int) -> np.ndarray:
    """(B, W, D) independent samples for conditions ``cond`` (B, W, C) (no prefix): one call."""
    import jax
    import jax.numpy as jnp

    cond = np.asarray(cond, np.float32)
    B, W = cond.shape[:2]
    zeros = jnp.zeros((B, W, model.dim), jnp.float32)
    x = _sampler(model)(model.variables, jnp.asarray(cond), zeros, jnp.zeros((B, W, 1), jnp.float32),
                        jax.random.PRNGKey(int(seed) & 0x7FFFFFFF))
    return np.asarray(x)


def sample_sequence(model: FlowModel, cond: np.ndarray, seed: int) -> np.ndarray:
    """(N, D) normalised motion features for a condition sequence ``cond`` (N, C) of any length N:
    overlapping windows, each continuing the previous one's last ``prefix_frames`` frames."""
    import jax
    import jax.numpy as jnp

    p = model.params
    W, P = int(p.window_frames), int(p.prefix_frames)
    cond = np.asarray(cond, np.float32)
    N = len(cond)
    if cond.ndim != 2 or cond.shape[1] != model.cond_dim:
        raise ConfigError(f"flow_matching: condition of shape {cond.shape}, the model reads {model.cond_dim} per frame")
    if N == 0:
        return np.zeros((0, model.dim), np.float32)
    hop = max(W - P, 1)
    starts = [0] + list(range(hop, max(N - P, 1), hop)) if N > W else [0]
    total = starts[-1] + W
    pad = np.concatenate([cond, np.repeat(cond[-1:], total - N, axis=0)]) if total > N else cond
    out = np.zeros((total, model.dim), np.float32)
    fn = _sampler(model)
    key = jax.random.PRNGKey(int(seed) & 0x7FFFFFFF)
    mask0 = np.zeros((1, W, 1), np.float32)
    maskp = mask0.copy()
    maskp[:, :P] = 1.0
    for i, s in enumerate(starts):
        prefix = np.zeros((1, W, model.dim), np.float32)
        mask = mask0
        if i > 0 and P > 0:
            prefix[0, :P] = out[s:s + P]
            mask = maskp
        x = fn(model.variables, jnp.asarray(pad[None, s:s + W]), jnp.asarray(prefix), jnp.asarray(mask),
               jax.random.fold_in(key, i))
        out[s:s + W] = np.asarray(x[0])
    if p.smooth_frames > 0:
        from scipy.ndimage import gaussian_filter1d

        out = gaussian_filter1d(out, float(p.smooth_frames), axis=0, mode="nearest")
    return out[:N]


def save_checkpoint(model: FlowModel, path: str | Path, extra: dict | None = None) -> None:
    """The model (and ``extra`` arrays, e.g. the normalisations) as msgpack, written atomically."""
    import flax.serialization
    import jax

    from ..utils import atomic_path

    blob = {"key": model.key, "dim": model.dim, "cond_dim": model.cond_dim, "losses": np.asarray(model.losses),
            "seconds": float(model.seconds), "cpu_seconds": float(model.cpu_seconds),
            "variables": flax.serialization.to_state_dict(jax.device_get(model.variables)),
            "extra": {k: np.asarray(v) for k, v in (extra or {}).items()}}
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        Path(tmp).write_bytes(flax.serialization.msgpack_serialize(blob))


def load_checkpoint(path: str | Path, params: FlowParams, key: str) -> tuple[FlowModel, dict] | None:
    """(model, extra) stored at ``path`` under ``key``, or None (absent, unreadable or another key)."""
    import flax.serialization
    import jax
    import jax.numpy as jnp

    path = Path(path)
    if not path.is_file():
        return None
    try:
        blob = flax.serialization.msgpack_restore(path.read_bytes())
        if blob.get("key") != key:
            return None
        dim, cdim, W = int(blob["dim"]), int(blob["cond_dim"]), int(params.window_frames)
        init = jax.eval_shape(lambda: _network(dim, params).init(
            jax.random.PRNGKey(0), jnp.zeros((1, W, dim)), jnp.zeros((1,)), jnp.zeros((1, W, cdim)),
            jnp.zeros((1, W, dim)), jnp.zeros((1, W, 1))))
        variables = flax.serialization.from_state_dict(init, blob["variables"])
    except Exception as e:  # noqa: BLE001 - an unreadable checkpoint is retrained, never trusted
        log.warning("ignoring unreadable flow-matching checkpoint %s (%s)", path, e)
        return None
    model = FlowModel(params, dim, cdim, variables, np.asarray(blob["losses"]), float(blob["seconds"]), key, True,
                      float(blob.get("cpu_seconds", float("nan"))))
    return model, {k: np.asarray(v) for k, v in blob.get("extra", {}).items()}
