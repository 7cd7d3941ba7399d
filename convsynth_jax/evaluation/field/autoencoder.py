"""The motion autoencoder whose latent codes the Fréchet gesture distance compares (GENEA 2022's
design, trained by us in JAX with flax and optax; no downloaded weights).

Input: windows of ``W`` frames (stride half a window) of root-relative, heading-free joint
positions, flattened per frame and z-normalised with the training set's mean and SD. Encoder:
1-D convolutions to 128, 64, 64 (stride 2) and 32 channels, then dense layers 256 -> 128 -> a 32-d
latent code; the decoder mirrors it (dense, nearest upsampling, convolutions). Loss: L1
reconstruction plus L1 of the frame-to-frame velocity; Adam.

The GENEA 2022 scripts trained their autoencoder on the very test set they then scored; we train on
motion disjoint from every evaluated window (the benchmark task says which corpus). A trained model
is saved under a key over the training data, the parameters and this module's source, reloaded
when the key matches and retrained when anything changes (the key is in the file name and inside
the file, so a stale checkpoint is never read).
"""
from __future__ import annotations

import hashlib
import logging
import time
from dataclasses import asdict
from pathlib import Path
from typing import Any, NamedTuple, Sequence

import numpy as np

from ...errors import ConfigError
from .fgd import frame_windows
from .params import AutoencoderParams

log = logging.getLogger(__name__)


class TrainedAutoencoder(NamedTuple):
    """window: frames per input window; variables: flax parameters; mean, std: (D,) input
    normalisation; key: the cache key; seconds: training time (0 when loaded); loss: final epoch's."""

    window: int
    dim: int
    variables: Any
    mean: np.ndarray
    std: np.ndarray
    key: str
    seconds: float
    loss: float
    params: AutoencoderParams


def _module(window: int, dim: int, p: AutoencoderParams):
    import flax.linen as nn
    import jax.numpy as jnp

    c1, c2, c3, c4 = p.channels
    k = p.kernel_size
    act = nn.leaky_relu

    class Encoder(nn.Module):
        @nn.compact
        def __call__(self, x):                        # (B, W, D) -> (B, latent)
            x = act(nn.Conv(c1, (k,), padding="SAME")(x))
            x = act(nn.Conv(c2, (k,), padding="SAME")(x))
            x = act(nn.Conv(c3, (k,), strides=(2,), padding="SAME")(x))
            x = act(nn.Conv(c4, (k,), padding="SAME")(x))
            x = x.reshape(x.shape[0], -1)
            for i, d in enumerate(p.dense):
                x = nn.Dense(d)(x)
                if i < len(p.dense) - 1:
                    x = act(x)
            return x

    class Decoder(nn.Module):
        @nn.compact
        def __call__(self, z):                        # (B, latent) -> (B, W, D)
            x = z
            for d in reversed(p.dense[:-1]):
                x = act(nn.Dense(d)(x))
            x = act(nn.Dense((window // 2) * c4)(x)).reshape(z.shape[0], window // 2, c4)
            x = jnp.repeat(x, 2, axis=1)
            x = act(nn.Conv(c3, (k,), padding="SAME")(x))
            x = act(nn.Conv(c2, (k,), padding="SAME")(x))
            x = act(nn.Conv(c1, (k,), padding="SAME")(x))
            return nn.Conv(dim, (k,), padding="SAME")(x)

    class AE(nn.Module):
        def setup(self):
            self.encoder = Encoder()
            self.decoder = Decoder()

        def __call__(self, x):
            return self.decoder(self.encoder(x))

        def encode(self, x):
            return self.encoder(x)

    return AE()


def _windows(relative: Sequence[np.ndarray], window: int) -> np.ndarray:
    """(N, W, D) float32 windows of every sequence (F, J, 3) flattened per frame."""
    ws = [frame_windows(np.asarray(r, np.float32).reshape(len(r), -1), window) for r in relative]
    ws = [w for w in ws if len(w)]
    if not ws:
        raise ConfigError(f"no sequence is as long as the autoencoder's window ({window} frames)")
    return np.concatenate(ws)


def cache_key(relative: Sequence[np.ndarray], window: int, params: AutoencoderParams) -> str:
    """sha256 over the training motion, the window, the parameters and this module's source."""
    h = hashlib.sha256()
    for r in relative:
        a = np.ascontiguousarray(np.asarray(r, np.float32))
        h.update(str(a.shape).encode())
        h.update(a.tobytes())
    h.update(repr((window, sorted(asdict(params).items()))).encode())
    h.update(Path(__file__).read_bytes())
    return h.hexdigest()


def train_autoencoder(relative: Sequence[np.ndarray], window: int, params: AutoencoderParams,
                      cache_dir: str | Path | None = None) -> TrainedAutoencoder:
    """An autoencoder of ``window``-frame windows trained on ``relative`` (sequences (F, J, 3) of
    root-relative positions), or the cached one with the same key."""
    import flax.serialization
    import jax
    import jax.numpy as jnp
    import optax

    from ...utils import atomic_path

    key = cache_key(relative, window, params)
    path = Path(cache_dir) / f"motion_ae_w{window}_{key[:20]}.msgpack" if cache_dir is not None else None
    data = _windows(relative, window)
    n, _, dim = data.shape
    mean = data.reshape(-1, dim).mean(axis=0)
    std = data.reshape(-1, dim).std(axis=0)
    # a coordinate that never moves in training (the root at the origin) keeps unit scale: dividing by
    # its ~0 SD would blow any deviation of evaluated motion up by orders of magnitude
    std = np.where(std > 1e-3 * max(float(std.max()), 1e-12), std, 1.0)
    x = (data - mean) / std
    model = _module(window, dim, params)
    rng = jax.random.PRNGKey(params.seed)
    init = model.init(rng, jnp.zeros((1, window, dim), jnp.float32))
    if path is not None and path.is_file():
        blob = flax.serialization.msgpack_restore(path.read_bytes())
        if blob.get("key") == key:
            variables = flax.serialization.from_state_dict(init, blob["variables"])
            log.info("autoencoder (%d frames) loaded from %s", window, path)
            return TrainedAutoencoder(window, dim, variables, np.asarray(blob["mean"]), np.asarray(blob["std"]), key,
                                      0.0, float(blob["loss"]), params)
    t0 = time.perf_counter()
    opt = optax.adam(params.learning_rate)
    state = opt.init(init)
    vw = float(params.velocity_weight)

    def loss_fn(v, xb):
        y = model.apply(v, xb)
        rec = jnp.mean(jnp.abs(y - xb))
        vel = jnp.mean(jnp.abs(jnp.diff(y, axis=1) - jnp.diff(xb, axis=1)))
        return rec + vw * vel

    @jax.jit
    def step(v, s, xb):
        loss, g = jax.value_and_grad(loss_fn)(v, xb)
        upd, s = opt.update(g, s, v)
        return optax.apply_updates(v, upd), s, loss

    bs = min(params.batch_size, n)
    gen = np.random.default_rng(params.seed)
    variables, loss = init, float("nan")
    for epoch in range(params.epochs):
        order = gen.permutation(n)
        losses = []
        for b in range(n // bs):
            variables, state, l_ = step(variables, state, jnp.asarray(x[order[b * bs:(b + 1) * bs]]))
            losses.append(l_)
        loss = float(np.mean(jax.device_get(losses)))
        log.debug("autoencoder w%d epoch %d loss %.4f", window, epoch, loss)
    seconds = time.perf_counter() - t0
    log.info("autoencoder (%d frames, %d windows) trained in %.1f s, loss %.4f", window, n, seconds, loss)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        blob = {"key": key, "variables": flax.serialization.to_state_dict(jax.device_get(variables)),
                "mean": mean, "std": std, "loss": loss}
        with atomic_path(path) as tmp:
            Path(tmp).write_bytes(flax.serialization.msgpack_serialize(blob))
    return TrainedAutoencoder(window, dim, variables, mean, std, key, seconds, loss, params)


def encode(model: TrainedAutoencoder, relative: np.ndarray, batch: int = 256) -> np.ndarray:
    """(N, latent) codes of the windows (stride half a window) of one sequence (F, J, 3); none
    when it is shorter than a window."""
    return encode_many(model, [relative], batch)[0]


def encode_many(model: TrainedAutoencoder, sequences: Sequence[np.ndarray], batch: int = 1024) -> list:
    """:func:`encode` of many sequences in shared batches (one list entry per sequence)."""
    parts = [frame_windows(np.asarray(r, np.float32).reshape(len(r), -1), model.window) for r in sequences]
    sizes = [len(p) for p in parts]
    if sum(sizes) == 0:
        return [np.zeros((0, model.params.dense[-1])) for _ in parts]
    codes = _encode_windows(model, np.concatenate([p for p in parts if len(p)]), batch)
    return np.split(codes, np.cumsum(sizes)[:-1])


def _encode_windows(model: TrainedAutoencoder, w: np.ndarray, batch: int) -> np.ndarray:
    import jax
    import jax.numpy as jnp

    if len(w) == 0:
        return np.zeros((0, model.params.dense[-1]))
    if w.shape[-1] != model.dim:
        raise ConfigError(f"autoencoder trained on {model.dim} values per frame, given {w.shape[-1]}")
    x = (w - model.mean) / model.std
    fn = _encoder_fn(model.window, model.dim, model.params)
    out = []
    for s in range(0, len(x), batch):
        xb = x[s:s + batch]
        pad = batch - len(xb)
        xp = np.concatenate([xb, np.zeros((pad,) + xb.shape[1:], xb.dtype)]) if pad else xb
        out.append(np.asarray(jax.device_get(fn(model.variables, jnp.asarray(xp, jnp.float32))))[:len(xb)])
    return np.concatenate(out).astype(np.float64)


_ENCODERS: dict = {}


def _encoder_fn(window: int, dim: int, params: AutoencoderParams):
    """The jitted encoder of one architecture (built once per window, size and parameters)."""
    import jax

    key = (window, dim, params)
    if key not in _ENCODERS:
        net = _module(window, dim, params)
        _ENCODERS[key] = jax.jit(lambda v, x: net.apply(v, x, method=net.encode))
    return _ENCODERS[key]
