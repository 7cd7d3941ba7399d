"""The gesture-generation field's numerical evaluation, for any system of the framework.

Metrics (every parameter in :class:`.params.FieldMetricParams`; positions in the BVH's units, times
in seconds): average jerk and acceleration and the Hellinger distance between histograms of moving
distance (:mod:`.kinematic`, GENEA numerical evaluations), canonical correlation analysis fitted once
per evaluation set (:mod:`.cca`), the Fréchet gesture distance on raw windows and on the features of
our own motion autoencoder (:mod:`.fgd`, :mod:`.autoencoder`), beat consistency (:mod:`.beat`,
EMAGE's definition) and L1 diversity and gesture area coverage (:mod:`.coverage`).
Slow loop references of each live in ``convsynth_jax.testing.field_metrics``.
"""
