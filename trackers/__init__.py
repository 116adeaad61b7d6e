"""Front end: detectors, feature tracking on raw fisheye frames, per-obstacle bearing tracks.

Imports from ``estimators`` only, never from ``pipeline``.
"""
