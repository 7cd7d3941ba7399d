"""Vectorized JAX search: a frame-synchronous stochastic beam over a padded adjacency.

Each output frame the B beam paths expand along their (at most D cheapest) out-edges; candidates
that break the frame's constraint mask die; B survivors are drawn without replacement with
probabilities proportional to exp(-cost / temperature) (Gumbel top-k), so cheap paths are likelier
but not certain — the stochastic greedy selection of the paper, done for all paths at once. The
frame count is padded to a bucket (multiple of 64) so one compile serves all windows of a graph.
"""
from __future__ import annotations

import time
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from .constraints import Constraints, is_peak_state
from .result import SearchResult, failed_segment_at, path_stats


def padded_adjacency(graph, max_degree: int = 64):
    """(S, D) targets (-1 padded) and costs (inf padded): each state's D cheapest out-edges."""
    deg = np.diff(graph.indptr)
    D = int(min(max(1, deg.max() if deg.size else 1), max_degree))
    S = graph.num_states
    adj = np.full((S, D), -1, np.int32)
    cost = np.full((S, D), np.inf, np.float32)
    for s in range(S):
        a, b = graph.indptr[s], graph.indptr[s + 1]
        t, c = graph.indices[a:b], graph.cost[a:b]
        if t.size > D:
            k = np.argsort(c, kind="stable")[:D]
            t, c = t[k], c[k]
        adj[s, :t.size] = t
        cost[s, :t.size] = c
    return adj, cost


_ADJ_CACHE: list = []  # small LRU of (graph, max_degree, adjacency); graphs are immutable


def _cached_adjacency(graph, max_degree):
    for g, d, val in _ADJ_CACHE:
        if g is graph and d == max_degree:
            return val
    val = padded_adjacency(graph, max_degree)
    _ADJ_CACHE.append((graph, max_degree, val))
    del _ADJ_CACHE[:-4]
    return val


def _ok(own_label, par_label, req):
    """Label requirements of one frame for states (any shape): req = (own, partner, own_not, partner_not)."""
    own_r, par_r, own_n, par_n = req
    ok = (own_r < 0) | (own_label == own_r)
    ok &= (par_r < 0) | (par_label == par_r)
    ok &= ~((own_n >= 0) & (own_label == own_n))
    ok &= ~((par_n >= 0) & (par_label == par_n))
    return ok


@partial(jax.jit, static_argnames=("beam",))
def _beam_kernel(key, adj, adj_cost, is_peak, own_label, par_label, reqs, pw, reset, check, temp, beam: int):
    S, D = adj.shape
    k0, key = jax.random.split(key)
    g0 = jax.random.gumbel(k0, (S,))
    flag0 = jnp.where(pw[0], is_peak, False)
    valid0 = _ok(own_label, par_label, tuple(r[0] for r in reqs)) & jnp.where(check[0], flag0, True)
    score0 = jnp.where(valid0, g0, -jnp.inf)
    top0, states0 = jax.lax.top_k(score0, beam)
    alive0 = jnp.isfinite(top0)
    cost0 = jnp.zeros(beam, jnp.float32)
    fl0 = flag0[states0]

    def step(carry, xs):
        states, cost, flag, alive, key = carry
        req_t, pw_t, reset_t, check_t = xs
        key, sub = jax.random.split(key)
        cand = adj[states]                                   # (B, D)
        cc = cost[:, None] + adj_cost[states]
        safe = jnp.maximum(cand, 0)
        f_prev = jnp.where(reset_t, False, flag)[:, None]
        f_new = f_prev | (pw_t & is_peak[safe])
        ok_t = _ok(own_label[safe], par_label[safe], req_t)
        valid = (cand >= 0) & alive[:, None] & ok_t & jnp.where(check_t, f_new, True)
        score = -cc / temp + jax.random.gumbel(sub, cc.shape)
        score = jnp.where(valid, score, -jnp.inf).reshape(-1)
        top, idx = jax.lax.top_k(score, beam)
        parent = idx // D
        new_states = safe.reshape(-1)[idx]
        new_cost = cc.reshape(-1)[idx]
        new_flag = f_new.reshape(-1)[idx]
        new_alive = jnp.isfinite(top)
        return (new_states, new_cost, new_flag, new_alive, key), (parent, new_states, new_cost, new_alive)

    init = (states0, cost0, fl0, alive0, key)
    rest = tuple(r[1:] for r in reqs)
    _, (parents, states, costs, alives) = jax.lax.scan(step, init, (rest, pw[1:], reset[1:], check[1:]))
    return states0, alive0, parents, states, costs, alives


def beam_search(graph, constraints: Constraints, cfg=None, seed: int = 0) -> SearchResult:
    """Beam search at ``search.temperature``; if no path survives, retry at each of
    ``search.retry_temperatures`` (hotter sampling keeps a more diverse beam: more windows solved,
    at the price of more synthetic transitions). The result reports the time of all attempts."""
    from .constraints import _get

    t0 = time.perf_counter()
    temps = [float(_get(cfg, "temperature", 0.05))] + [float(t) for t in (_get(cfg, "retry_temperatures", []) or [])]
    for k, temp in enumerate(temps):
        res = _beam_search_once(graph, constraints, cfg, seed + 1000 * k, temp)
        if res.success:
            break
    res.seconds = time.perf_counter() - t0
    return res


def _beam_search_once(graph, constraints: Constraints, cfg, seed: int, temperature: float) -> SearchResult:
    from .constraints import _get

    t0 = time.perf_counter()
    beam = int(_get(cfg, "beam_size", 256))
    max_deg = int(_get(cfg, "max_degree", 64))
    adj, adj_cost = _cached_adjacency(graph, max_deg)
    syn = graph.cost[graph.synthetic]
    temp = max(temperature * (float(np.median(syn)) if syn.size else 1.0), 1e-6)
    T = constraints.num_frames
    Tp = int(np.ceil(T / 64) * 64)
    pad = Tp - T

    def padb(x, v):
        return np.concatenate([x, np.full((pad,) + x.shape[1:], v, x.dtype)]) if pad else x

    c = constraints
    free = np.full(T, -1, np.int32)
    reqs = tuple(jnp.asarray(padb(np.asarray(x if x is not None else free, np.int32), -1))
                 for x in (c.own_req, c.partner_req, c.own_not, c.partner_not))
    pw, reset, check = padb(constraints.peak_window, False), padb(constraints.peak_reset, False), padb(constraints.peak_check, False)
    beam = min(beam, graph.num_states)
    out = _beam_kernel(jax.random.PRNGKey(seed), jnp.asarray(adj), jnp.asarray(adj_cost),
                       jnp.asarray(is_peak_state(graph)), jnp.asarray(graph.own_label, jnp.int32),
                       jnp.asarray(graph.partner_label, jnp.int32), reqs, jnp.asarray(pw), jnp.asarray(reset),
                       jnp.asarray(check), jnp.float32(temp), beam=beam)
    states0, alive0, parents, states, costs, alives = (np.asarray(x) for x in out)
    alive_any = np.concatenate([[alive0.any()], alives[:, :].any(axis=1)])[:T]
    seconds = time.perf_counter() - t0
    if not alive_any.all():
        fail = int(np.argmin(alive_any))
        return SearchResult(False, None, float("inf"), 0, constraints.total, 0, fail,
                            failed_segment_at(constraints, fail), seconds, "beam")
    if T == 1:
        path = np.array([states0[np.argmax(alive0)]])
    else:
        last = T - 2
        live = alives[last]
        b = int(np.argmin(np.where(live, costs[last], np.inf)))
        path = np.empty(T, np.int64)
        for t in range(last, -1, -1):
            path[t + 1] = states[t, b]
            b = int(parents[t, b])
        path[0] = states0[b]
    total, nsyn, tc = path_stats(graph, path)
    return SearchResult(True, path, total, nsyn, constraints.total, constraints.total, None, None,
                        time.perf_counter() - t0, "beam", tc)
