"""Every numeric tolerance the tests use, in one place."""
FK_FLOAT64 = 1e-6          # FK vs float64 NumPy reference (file units)
ROUND_TRIP = 1e-4          # BVH save -> load, global positions (file units)
ROTATION = 1e-5            # rotation conversions vs scipy (float32 kernels)
COST_FLOAT32 = 1e-3        # relative: JAX float32 costs vs float64 reference
COST_FLOAT64 = 1e-9        # relative: JAX float64 costs vs float64 reference
THRESHOLD_TIE = 1e-5       # relative: pairs this close to the threshold are excluded from edge-set equality
F0_RELATIVE = 0.05         # Praat F0 vs planted contour


def enable_x64():
    """Context manager enabling float64 in JAX (jax.enable_x64 in new versions, experimental before)."""
    import jax

    fn = getattr(jax, "enable_x64", None)
    if fn is None:  # pragma: no cover - older JAX
        from jax.experimental import enable_x64 as fn
    return fn(True)
