"""Realization: poses along a path, blending, root integration, blinks, the per-character pipeline."""
