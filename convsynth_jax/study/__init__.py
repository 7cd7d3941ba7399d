"""The perceptual study kit (paper Section 8, Figure 6): stimuli, a web application that collects
forced-choice answers, and their analysis.

- :mod:`.design`: which segments and pairs become stimuli, left/right balance, attention checks,
  each participant's trials (pure functions of a seed);
- :mod:`.build`: a finished study folder (videos, ``manifest.json``/``manifest.csv``) from a corpus
  and a synthesis system; the side-by-side videos are drawn by :mod:`convsynth_jax.render` (both
  characters in a three-quarter view, audio muxed in), the project's one renderer;
- :mod:`.store`: the SQLite store (WAL) of participants and answers;
- :mod:`.server`: the web application (FastAPI; the optional ``study`` extra);
- :mod:`.analyze`: exported answers -> per-pair counts -> Figure 6's tests.

The package sits just below ``tasks`` (import-linter): no library module imports it.
"""
