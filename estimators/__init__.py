"""Geometry and estimation: camera models, rigs, ego-motion, triangulation, bounds, fusion.

The bottom layer of fisheye-des: it imports nothing from ``trackers`` or ``pipeline``.
"""
