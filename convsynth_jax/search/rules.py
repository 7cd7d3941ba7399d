"""The per-frame rules both search kernels share: the packed state code, the ``paper`` rule of both
channels for one edge, and which states may start a path. The beam search (:mod:`.beam`) and the
look-ahead (:mod:`.feasible`) apply them; keeping them here keeps those two free of each other."""
from __future__ import annotations

import jax.numpy as jnp

from .constraints import label_ok, paper_channel_step


def unpack_code(x):
    return x & 15, (x >> 4) & 15, ((x >> 8) & 1).astype(bool)


def paper_step(label_x, info_x, own_y, par_y, info_y, syn, first, t, flag, own_t, par_t, codes, tol):
    """Both channels' ``paper`` rules (constraints.paper_channel_step); flag bit 0 own, bit 1 partner."""
    own_x, par_x = label_x
    ok_o, fo = paper_channel_step(own_x, info_x[..., 0], info_x[..., 1], own_y, info_y[..., 0], info_y[..., 1],
                                  info_y[..., 2], syn, first, t, (flag & 1) == 1, own_t, codes[0], tol)
    ok_p, fp = paper_channel_step(par_x, info_x[..., 3], info_x[..., 4], par_y, info_y[..., 3], info_y[..., 4],
                                  -1, syn, first, t, (flag & 2) == 2, par_t, codes[1], tol)
    return ok_o & ok_p, fo.astype(jnp.int32) | (fp.astype(jnp.int32) << 1)


def start_rule(state_code, info, reqs, pw, check, paper_arrs, num_states, paper: bool):
    """(valid (S,), flags (S,)) of every state as the path's frame-0 state (both kernels)."""
    S = state_code.shape[0]
    own0, par0, peak0 = unpack_code(state_code)
    valid0 = label_ok(own0, par0, tuple(r[0] for r in reqs))
    if paper:
        own_a, par_a, codes, tol = paper_arrs
        ok0, flag0 = paper_step((own0, par0), info, own0, par0, info, jnp.zeros(S, bool), jnp.ones(S, bool), 0,
                                 jnp.zeros(S, jnp.int32), tuple(a[0] for a in own_a), tuple(a[0] for a in par_a),
                                 codes, tol)
        valid0 &= ok0
    else:
        flag0 = pw[0] & peak0
        valid0 &= jnp.where(check[0], flag0, True)
    return valid0 & (jnp.arange(S) < num_states), flag0
