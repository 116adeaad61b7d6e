"""Front end: detectors, feature tracking on raw fisheye frames, per-obstacle bearing tracks.

Imports from ``estimators`` only, never from ``pipeline``.

- ``trackers.detectors``: the ``Detector`` interface and ``Detections`` record, a registry by name
  (``orb`` default, ``navlights``, ``kornia``, ``torch``) and the entry-point group
  ``fisheye_des.detectors`` for outside plug-ins (``make_detector(name, **options)``).
- ``trackers.features``: ``FeatureTracker`` per camera: pyramidal KLT with forward-backward and
  residual checks on the raw frame masked to the lens circle, re-detection where the coverage grid
  thins, ORB descriptors to re-acquire features lost for a few frames; every feature has a stable id
  and a ring-buffer history of uv, b_C, b_B and t_s.
- ``trackers.grouping``: ``ObstacleGrouper`` (features -> obstacle tracks by angular proximity and
  consistent motion; stable ids; tentative -> confirmed -> lost; a representative bearing moved by
  the members' mean motion) and ``BoxTracker`` (box detectors).
- ``trackers.association``: the spherical epipolar constraint, descriptor matching under it and
  stereo KLT between cameras.
- ``trackers.frontend``: ``FrontEnd(rig, detector="orb", **options).process(images, frame, t_s)``
  -> ``list[estimators.records.ObstacleObservation]``, with ``timings`` per stage. Feature ids in
  the CameraViews are physical-point ids: a feature matched across cameras carries the reference
  camera's id in every view.
- ``trackers.benchmark``: ``python -m trackers.benchmark SCENE_DIR`` measures frame rate, coverage
  of the simulator's obstacles and id switches.
"""
