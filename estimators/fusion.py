"""Per-obstacle Kalman filter fusing bearings, parallax / stereo triangulations and moving-obstacle bounds.

One filter per obstacle track. State ``x = [p_W (3), v_W (3)]``: the obstacle's position (m) and
velocity (m/s) in the world frame W, covariance ``P`` (6, 6). Time steps come from ``t_s`` only.

Why filterpy's ``ExtendedKalmanFilter`` (and not the UKF)
    * The bearing measurement is fused as a 2-D residual in the tangent plane of the *predicted*
      ray (gnomonic coordinates, below). Its Jacobian is exact and closed form,
      ``H = [E^T / rho, 0]``, so the EKF's linearisation costs nothing and is accurate once the
      track is initialised; a UKF would need a residual function on the sphere and 13 sigma points
      per update for the same first-order result.
    * The nonlinearity that does hurt bearing-only filters is a huge range uncertainty at start
      (the sigma points / linearisation straddle a 1-to-100 m depth range). We avoid it by
      *delayed initialisation*: a track's filter starts only from a triangulation with enough
      parallax (mono) or from a stereo fix, with its first-order covariance. From then on the
      relative range uncertainty is <~ 10 % and the EKF is well inside its linear regime.
    * It is ~5x cheaper per update than the UKF (matters with tens of tracks at 30 fps).

Process model (constant velocity, continuous white-noise acceleration of spectral density q):
    F = [[I, dt I], [0, I]],   Q = q [[dt^3/3 I, dt^2/2 I], [dt^2/2 I, dt I]],   q = a^2 tau
with tau = ``accel_time_s``: the velocity changes by about a * tau over tau (Bar-Shalom, Li and
Kirubarajan 2001, sec. 6.2.2: sqrt(q T) ~ a_max T, with a fixed time scale tau instead of the frame
interval, so that Q does not depend on the frame rate). Two hypotheses:
    * ``moving`` (a track any stereo fix has fed): ``a = max_accel_mps2``, velocity prior from the
      max speed. Velocity is observable from successive stereo fixes and is reported.
    * ``static`` (mono-only tracks): ``a = static_accel_mps2`` and a tight zero-mean velocity prior.
      A single camera flying straight cannot separate range from obstacle velocity (any point
      ``(1 - s) c(t) + s p`` gives the same bearings), so mono ranging *must* assume a (nearly)
      stationary obstacle, as the thesis does (sec. 3.3.1). The moving case is covered by the bounds
      (sec. 3.3.2), which constrain the estimate; mono tracks never report a velocity.

Measurements
    * Bearing of camera c at the drone's pose at t_s: camera centre ``c_W`` and unit bearing
      ``b_W = R_W_C b_C`` with ``T_W_C = T_W_B(t_s) @ T_C_B^-1``. Residual in the tangent plane of
      the predicted ray ``u = (p - c_W) / rho``, rho = |p - c_W|, basis E (3, 2) orthonormal to u:
          z = E^T b_W / (u . b_W)        (gnomonic coordinates; never wrapping angles)
          h(x) = 0,  H = [E^T / rho, 0_(2x3)],  R = sigma^2 I_2
    * Stereo from features: when two cameras' views of a track share feature ids (the same
      physical points), each shared feature is triangulated from its two rays of this frame and
      the fix is the point on the first camera's representative ray at their median range
      (``_feature_stereo``); it is fused as a point (never the second camera's representative
      bearing, which lies on another part of the object: the ghost of centroid stereo). Two views
      that list member features but share none of them (or too few for that fix though each lists
      enough) are not one point either: no stereo fix, only the first view's bearing
      (``_ghost_prone``). Otherwise (views sharing a feature, views without member features: box
      tracks, bearings mode) the representative bearings are triangulated, as follows.
    * Stereo: when two cameras see the track in one frame, ``geometry.triangulate`` gives a point.
      It initialises the track (moving hypothesis) and switches a mono-initialised track to the
      moving hypothesis. The update itself fuses the two cameras' bearings as above, not the
      triangulated point as a 3-D position (z = p_tri, H = [I 0], R = sigma_r^2 u u^T + (depth
      sigma_b)^2 (I - u u^T)); never both (double counting). Bearings won on the accuracy harness
      (0.30 m baseline, 0.5 px): median range error within 8 m 1.7 % vs 2.5 %, speed 8.9 % vs
      11.7 %, 1-sigma share 71 % vs 49 %, because the triangulated range's noise is skewed (range ~
      1 / parallax: at 8 m one frame's sigma is ~10 %) while the bearing noise is Gaussian and the
      prior keeps the EKF linear; the point update (a former ``stereo_update: point``, removed in
      session 29) is kept for a feature stereo fix only, below.
    * Mono parallax triangulation: the current bearing against the sighting with the longest
      baseline within ``baseline_max_age_s`` (the thesis: a longer baseline ranges farther; the age
      limit keeps a moving obstacle from corrupting it). It initialises the filter once its
      parallax >= ``min_parallax_rad``; the filter state then starts at the earlier sighting and the
      bearings in between are replayed (each sighting's views as ``_process`` fuses them: the first
      one alone when the two cameras' are likely different points, ``_ghost_prone``), so no
      sighting is wasted and none is used twice. After
      that every new bearing is fused directly, which accumulates the parallax of the whole flight
      (fusing the triangulation as well would count the same bearings twice). Its range is reported
      only while a bearing it was not triangulated from has tested it and the latest such test
      passed the gate (``_Track.pair_tested``; the replayed bearings count): two rays meet whatever
      their errors, their one residual dof is the miss across their epipolar plane, so an error
      along that plane (a bearing's jump, the obstacle's own motion in it) moves the point with no
      residual, and a gated bearing says the static point is not where the bearings are.
    * Member features (``feature_ranging``): when the front end lists a track's member features
      (KLT corners: fixed physical points, unlike its representative bearing, a smoothed centroid
      of members at different depths that slides over the object as members come and go), each
      feature is triangulated from all its rays so far (least squares, ``_FeatureRays``: one store
      per run keyed by the physical-point feature id, so the rays of every camera and frame meet;
      old rays fade with ``feature_memory_s``) and a static-hypothesis track's point is set on its
      representative ray at the median feature range (sigma from the features' spread). All
      tracks' features are processed in one vectorised pass per frame (``_features_batch``).
      This estimate is cumulative, so it replaces the
      state instead of being fused each frame. On the simulator's mono_straight scene rendered and
      tracked (pipeline mode) it raised the share of ranged reports from 10 % to 91 % and cut the
      median range error from 19 % to 4 %.
    * Moving-obstacle bounds (thesis eq. 3.11-3.13 generalised: ``geometry.moving_obstacle_bounds``
      with max displacement = max speed * dt), widened for bearing noise (below), are reported as
      ``range_min_m`` / ``range_max_m`` and constrain the estimate: when the estimated range leaves
      them a range pseudo-measurement at the violated bound is fused (h = |p - o_W|,
      H = [u^T, 0], R = (bounds_pseudo_sigma_frac * bound)^2), a soft estimate projection. Only
      static-hypothesis (mono) tracks are constrained: stereo measures the range itself, while the
      bounds rest on the assumed max speed (an obstacle faster than it gets wrong bounds).
    * Gating: each bearing (2 dof) / stereo point (3 dof) update is rejected when its NIS
      ``y^T S^-1 y`` exceeds the chi-square quantile of ``gate_probability``; rejections are
      counted (``gated``), and after ``reinit_after_gated`` consecutive rejections the filter is
      restarted (``_restart``, below).
    * Member-set replacement (``member_reset_frac``): when more than that share of a track's
      member feature rays (with >= 2 of them now and in the frame it was last seen: a share of
      one ray says nothing) were not its members in that frame, the front end has handed the id
      to another set of points (a confirmed track taking over a younger one of the same
      obstacle, trackers/grouping). Its state, covariance, sightings (mono baselines, bounds)
      and velocity reference belong to the old points, so the filter is restarted.
    * Restart (``_restart``, the one path for both causes above): the filter, sightings, bounds,
      velocity reference and evidence and the moving hypothesis are dropped; the track keeps its
      id, label, gate counters and sources and starts again from this frame's measurements
      (feature points, stereo fix, or a fresh mono pair) instead of reporting the old state with
      its old, small covariance.

Bounds under bearing noise: the exact geometric interval of two *noisy* rays can miss the truth.
Ray a is projected into the epipolar plane of (baseline, ray b) (a superset: for points in that
plane the distance to the projected ray is never larger), ray b is turned in that plane by
0 and +-delta, and so, with ray b as seen, is ray a (about its own centre), delta =
``bounds_noise_sigmas`` * sqrt(sigma_a^2 + sigma_b^2); the reported interval is the union of them.
Turning ray b alone does not cover ray a's error: an end of the interval moves by r delta cot(phi)
when ray b turns (r its depth, phi the angle between the rays) but by s eps / sin(phi) when ray a
turns by eps (s the depth on ray a), so near phi = 90 deg (an obstacle abeam, or crossing at the
speed limit) ray b's turns hardly move it: an obstacle at the speed limit, moving across ray a,
5 m of baseline, 1 mrad noise on ray a alone, was inside 68 % of the time (81 % abeam), 100 % with
ray a's turns. The earlier ray is the oldest sighting in the baseline window (the longest
time, so the widest motion allowance, but also the longest baseline).
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter

from estimators import geometry
from estimators.cameras import _tangent_basis  # (N, 3) unit rows -> (N, 3, 2) across them
from estimators.egomotion import EgoMotion
from estimators.errors import ConfigError, InputError, frame_at
from estimators.fusion_stats import chi2_ppf, median_variance_factor
from estimators.geometry import (
    _cross,  # a x b of (3,) or (K, 3) rows, np.cross without its overhead
    _einsum,  # np.einsum without its Python-level wrapper
    _isin,  # np.isin of integer arrays without its overhead
    _norm,  # |x| of a 1-D array, np.linalg.norm's own formula without its dispatch
)
from estimators.records import ObstacleObservation, TrackReport
from estimators.rig import Rig
from estimators.se3 import Pose

__all__ = ["STAGES", "FusionSettings", "ObstacleFusion"]

# the stages ``ObstacleFusion.timings`` gives each step (seconds): see ``ObstacleFusion.__init__``
STAGES: tuple[str, ...] = ("estimate", "fuse")


@dataclass(frozen=True)
class FusionSettings:
    """Tuning of :class:`ObstacleFusion`. SI units; angles in radians.

    Attributes:
        max_speed_mps: largest obstacle speed (m/s) the bounds allow; None = the drone's own speed at
            the two sightings (the thesis's assumption, sec. 3.3.2). Default None.
        max_accel_mps2: largest obstacle acceleration (m/s^2), the process noise of moving
            (stereo-fed) tracks. Default 1.0. Measured on random stereo scenes (constant-velocity
            obstacles at 1.5-9 m, 0.5 px): median speed error 13.6 % / 8.7 % / 5.2 % for 2 / 1 /
            0.5 m/s^2 with the same NEES; lower values lag behind manoeuvring obstacles.
        accel_time_s: time scale tau (s) of the process noise, q = a^2 tau. Default 0.1.
        static_accel_mps2: process noise (m/s^2) of the stationary hypothesis of mono-only tracks.
            Default 0.005. Small on purpose: a bearing-only track's lateral sigma is millimetres, so
            any larger velocity allowance makes the filter under-confident (NEES well below its dof);
            raise it when the front end's representative point drifts over the obstacle.
        static_velocity_sigma_mps: velocity prior sigma (m/s) of a mono-initialised track.
            Default 0.002.
        velocity_prior_sigma_mps: velocity prior sigma (m/s) of a stereo-initialised track; None =
            the max speed (or the drone's speed, at least 1 m/s). Default None.
        bearing_sigma_floor_rad: smallest bearing sigma used (rad), whatever the front end says.
            Default 5e-4 (about 0.2 px of a 195-degree 1280-px fisheye).
        gate_probability: chi-square gate probability for bearing / stereo updates. Default 0.999.
        min_parallax_rad: parallax needed to initialise a mono track from two sightings (rad), and
            for a member feature's point to count on a stereo rig (on a mono rig that floor is 10
            feature_sigma_rad: _features_batch). Default 1 degree.
        stereo_max_rel_sigma: a stereo triangulation is used only when range_sigma / range is at
            most this (else its two bearings are fused instead). Default 0.3.
        mono_init_max_rel_sigma: a mono track is initialised only from a triangulation with
            range_sigma / range at most this. Default 0.1 (at 0.3 the skewed 1/parallax error made
            the first half-second inconsistent: NEES 30+ right after initialisation).
        feature_ranging: for static-hypothesis (mono) tracks whose observations list member
            features, range from the features (below) instead of the representative bearing's
            parallax. Default True.
        feature_sigma_rad: bearing sigma of one member feature (rad) on a camera of focal length
            ``feature_sigma_focal_px`` (below). Default 1e-3.
        feature_sigma_focal_px: the focal length (px/rad) feature_sigma_rad holds for; on a rig
            whose cameras' pixels are coarser, f (the smallest px per rad at the image centre of its
            cameras, d uv / d b_C on the axis: fx, fy for Equidistant) below it,
            the member features' bearing sigma is feature_sigma_rad * feature_sigma_focal_px / f:
            the pixel part of a tracked feature's error (KLT, the detector's corner) scales with a
            pixel's angle. Finer pixels keep feature_sigma_rad (its non-pixel part, a corner's
            drift over the surface, does not shrink with them). None = feature_sigma_rad on every
            rig. Default 204.52395028133697, the focal length of the simulator's 195-degree 1280x720
            renders that feature_sigma_rad and feature_point_sigma_k were fitted on (every tuned,
            held-out and validation scene), so those are unchanged. Measured (two-ray points of
            shared features, error over their first-order sigma at 1e-3 rad, median |z|; Gaussian
            0.67): 0.57 / 0.70 on stereo_flying / its held-out twin at 204.5 px/rad, 1.01 on the
            demo's 640x360 render at 102.3 px/rad, where the scaled sigma is 2e-3 rad.
        feature_min_count: features with enough parallax needed for a feature range. Default 3.
        feature_inner_half: use only the half of them angularly nearest the representative ray
            (the range is the one along that ray; a near object's depth extent is a sizable share
            of its range). Default True.
        stereo_feature_min_count: features seen by both cameras of a frame needed for a stereo
            fix from them (instead of the two representative bearings). Default 2.
        feature_memory_s: time constant (s) of the exponential forgetting of a feature's old rays
            (a KLT corner drifts over the object). 0 = keep all. Default 0.5 (tracked mono_straight:
            median / p90 range error 4.3 % / 15.0 % vs 5.1 % / 16.7 % keeping all rays).
        feature_slide_memory_s: time constant tau_s (s) of a second, short forgetting of every
            feature's rays (0 = off): on a rig of two cameras or more, a feature whose newest rays
            (weights exp(-dt / tau_s)) no longer meet its point beyond the noise and the parallax
            they span (``_slid_features``: a corner that slid onto another physical point, e.g.
            the edge of a nearer obstacle passing in front, or a stereo match that moved to another
            point) ranges nothing, neither as a track's feature point nor as a carried state's
            point, until its rays agree again. Default 0.1, the thesis's interval (sec. 3.2.2; not
            fitted). Not on a mono rig: there the newest rays' depth rests on the flight over tau_s
            alone (a short baseline along which a slide in the flight's epipolar plane looks like
            a static point at another depth), and a dropped feature leaves the track to its other
            features only; on the tuned set it was a trade there (accuracy --set all replayed over
            one recording of 8ee88c1's front end, on every rig: tuned mono median 1.058 -> 1.184 %,
            p90 3.02 -> 3.08 %, held-out mono coverage 95.56 -> 94.88 %). On stereo rigs only, off
            -> on, replayed over one recording of 4f994d8's front end (tuned | held-out | validation
            | demo): range NEES 0.983 -> 0.949 (below its 95 % interval's 0.951) | 1.512 -> 1.500 |
            1.751 -> 1.736 | 1.386 -> 1.110, stereo <= 3 m 0.60 -> 0.63 | 0.61 -> 0.66 | 0.79 ->
            0.76 | 1.42 -> 1.31 %, <= 8 m 1.24 -> 1.16 | 0.93 -> 0.94 | 0.94 -> 0.92 | 1.73 -> 1.60
            %, stereo obstacle-frame coverage 88.45 -> 87.76 | 84.79 | 88.95 | 86.88 -> 85.00 %,
            every scored report's p90 (demo) 9.51 -> 9.09 %: a trade.
        stereo_spread_weight: weight of the shared features' range spread (1.4826 MAD) added to
            the reported range sigma of feature-stereo tracks (not filtered: the offset between the
            representative ray's surface point and the features does not average out over frames).
            Default 0.6, fitted on the tracked stereo_hover scene (1-sigma share 23 / 42 / 53 / 80 /
            97 % for weights 0 / 0.3 / 0.5 / 0.7 / 1).
        feature_ranging_moving: also range stereo-fed (moving-hypothesis) tracks from their
            member features' multi-view points when those fit static points (chi test below);
            the features' rays of both cameras and all frames then replace the per-frame stereo
            fix. Default True (tracked stereo_flying, shared ids: median error within 3 m / 8 m
            2.9 % / 3.1 % vs 7.4 % / 5.9 % with the per-frame feature stereo; stereo_hover the same).
        feature_mad_all_weight: weight w of the spread of all kept features in the feature range
            sigma (see _features_batch). Default 0.5 (tracked mono_straight replay, with
            feature_small_n_inflate 1: 1-sigma share 70.5 %, range NEES mean / median 13.5 / 0.30
            vs 70.2 %, 15.6 / 0.27 with w = 1 and no inflation; range errors unchanged).
        feature_small_n_inflate: k in the (1 + k / n) widening of the feature range sigma from n
            inner features (a median of few features is far less sure than its MAD says). Default 1
            (k = 2: NEES mean 8.8 but 1-sigma share 74 %, bulk under-confident).
        feature_static_chi: largest median normalised ray residual (chi, ~1 for static points:
            each ray's miss over sigma_f times that ray's own depth, see _features_batch)
            for which the features are taken as static; above it the feature range is not used
            (a moving obstacle). Default 9.
        feature_static_behind: on a mono rig, a member feature whose bearing turned by the parallax
            floor but whose rays meet behind (or at) the camera is no static point in front of it
            (its rays diverge: a moving point); it ranges nothing, and it fails the static-point
            test above: it enters the median as a failed vote, and when such features carry more
            of the track's ray evidence (residual dof, 2n - 3 for n rays) than the features that
            meet in front, the test fails outright. Default True (False: such features are left
            out of the test, as before).
        restart_keeps_motion: a member-replacement restart (``member_reset_frac``) keeps the
            obstacle's measured velocities that reject zero (``motion_carry``: the velocity
            evidence and the moving filter's velocity, assumed or not, each kept as the tests
            before the restart used it, ``_motion_evidence``): the front end handed
            the id to other points of the same obstacle, so the state and sightings belong to the
            old points but the motion belongs to the obstacle. While one of them, its covariance
            grown by the moving process noise, rejects zero (``_carried_moving``), the restarted
            track is not ranged from static feature points (a moving obstacle's fresh corners,
            tracked by one camera of a flying rig, fit static points at a wrong depth: motion along
            the flight's epipolar planes moves a bearing as a static point at another depth does).
            It decides only that (no velocity report, no member-spread change). Default True (the
            demo's track 121, a fragment of the moving box, ranged 0.65 m against 0.97 m at sigma
            0.013 m right after such a restart, 44 % of the demo's z^2 sum; accuracy --set all
            replayed over one recording of 804cf02's front end: demo range NEES 2.436 -> 1.640,
            z^2 > 9 5.02 -> 4.88 %, stereo <= 3 m 1.409 -> 1.400 %, moving stereo-rig p90 19.96 ->
            18.91 %; validation NEES 1.977 -> 1.977, stereo <= 8 m 1.0144 -> 1.0148 %; tuned and
            held-out unchanged). The filter's velocity is kept when ``vel_assumed`` too (since
            dm31: the demo's track 119 at 2.567 s, whose velocity its successive stereo fixes of one
            corner had measured, -1.33 +- 0.29 m/s, with too few shared corners for a feature
            velocity: 0.60 m against 0.92 m at sigma 7 mm, z^2 2059, after the restart).
        stereo_jump_check: a shared feature whose two-ray stereo point moved since its last one
            by more than the obstacle's motion (velocity prior) and both points' noise allow
            (``_stereo_jumps``) is not used that frame (its two cameras' rays are on two physical
            points: a stereo-KLT match on another period of a repeated texture, or sliding along
            an edge). Default True (val2_heldout_stereo_flying track 145: a stereo fix from two such
            features put a just-restarted track at 1.35 m on 3.48 m, z^2 1536; accuracy --set all
            replayed over one recording, with restart_keeps_motion: validation range NEES 1.977 ->
            1.845, z^2 > 9 3.38 -> 3.34 %, speed 0.514 -> 0.499 %, moving stereo-rig p90 7.33 ->
            6.57 %; worse: validation stereo <= 3 m 0.909 -> 0.918 %, <= 8 m 1.015 -> 1.018 %,
            1-sigma 74.01 -> 73.95 %, 13 fewer ranged reports; tuned, held-out and demo unchanged.
            Of the points it refuses, most are not cross-camera mismatches by the renderer's truth:
            it is a coarse test).
        feature_max_chi: with feature_point, the largest chi of one feature, its rays' mean squared
            miss over 2 (sigma_f d)^2 with d its CURRENT depth (the statistic it was chosen with;
            the static-point test above uses each ray's own depth instead) (a stereo id mismatch
            or a corner sliding along an edge fits no static point; stereo_hover track 23: a
            feature at 0.35 m with chi 34 ranged a pole at 1.3 m). Default 36 (the per-feature sigma
            is ~3x small, so good features reach chi ~9; tracked scenes: mono p90 4.9 / 4.7 / 5.5 %
            for no cut / 36 / 16).
        feature_point: range a track at the own least-squares point of its median member feature
            (the lower median by range of the inner half; for feature stereo the midpoint of the
            median shared feature's two rays) instead of at the median range along the
            representative ray. The representative ray is a centroid: on a convex obstacle it hits
            the nearest surface while the features sit deeper, and on a track that also holds
            background features it can cross another object (accuracy analyst's replays of the 5
            tracked pipeline scenes, 2026-11-22: 98 % of the mono > 5 % errors were over-ranges).
            The reported bearing then follows that point. Default True.
        moving_mono_max_s: a moving-hypothesis (stereo-fed) track seen by one camera only reports no
            range once its last range measurement (stereo fix, feature range) is older than this
            (s): bearings alone do not range a moving obstacle. Default 0.3.
        feature_min_depth_m: a feature's point must lie this far (m) in front of the camera (rays from
            one place, e.g. hovering, meet at the camera centre). Default 0.1 (tracked stereo_hover:
            range NEES mean 1729 -> 8.5 against 0: a stereo track ranged 0.35 m from such points).
        feature_point_sigma_k: a tracked feature's error over feature_sigma_rad where one ray's (or
            one two-ray point's) error is needed: the uses listed at the end, the feature stereo
            (two-ray) fix's sigma and its member points' (``_feature_stereo``), the slide and
            stereo-jump tests. Default 1.9. Until mono_point_sigma_k it was also the k of a mono
            rig's static-point sigma, hypot(max(k, sqrt(s2_f), sqrt(chi_now)) sigma_r,f, floor r),
            where it was fitted: 1.9, refitted on the tuned set after the window term and
            stereo_point_sigma_k (ed0a1ba..4f89bc7) left k 2.0's tuned range NEES at 0.940, below
            its interval [0.951, 1.050]: the largest k on a 0.1 grid back inside it (the least
            change). Replays of one recording of dc7a7aa's front end (accuracy --set all), tuned |
            held-out | validation | demo, k 2.0 / 1.9 / 1.8: range NEES 0.940 / 0.963 / 0.981 |
            0.983 / 0.985 / 0.976 | 1.491 / 1.514 / 1.538 | 1.006 / 1.000 / 0.948, 1-sigma 77.2 /
            77.0 / 79.1 | 78.4 / 78.0 / 77.9 | 77.5 / 77.0 / 77.0 | 77.6 / 78.3 / 80.3 %; 2.0 -> 1.9:
            held-out mono coverage 95.56 -> 95.39 %, demo stereo <= 3 m 1.31 -> 1.28 %, demo speed
            3.23 -> 3.34 %, heading 1.58 -> 1.64 deg, every other target line within 0.02. Before:
            2.0, the smallest of 1.75 / 2 / 2.25 / 2.5 that kept the tuned set's
            range NEES mean within its 95 % interval (replay over the front end of d59c4ac, with
            the current-ray term: 1.126 / 1.044 / 0.945 / 0.876; 1-sigma share 73.7 / 75.1 / 78.7 /
            80.3 %), refitted after the rays' own depths entered sigma_r,f (c046719: larger on
            approach). That front end had grouping step 3e on (5f4999b; off again since bdcb28d);
            on the default front end, with the stereo static outline rule, k 2.0 gives a tuned
            range NEES mean of 1.013 (median z^2 0.229, 1-sigma 75.4 %; accuracy --set both at
            cb37d6f). It was 2.5 (per-feature errors on the tracked scenes: median |z| 2 at
            sigma_f = 1e-3 rad, with the current depth). The same k sigma_f, unfitted for these
            uses, is also the bearing sigma of a feature ray in the supported-point update
            (``_supported_update``), the angle gate of a representative-ray triangulation's nearest
            member (sqrt(gate) k sigma_f), and the per-point error of the stereo feature
            velocity (``_feature_velocity``): k was
            fitted on position errors, which include a tracked corner's fixed offset from the
            surface point; that offset cancels in a displacement, so it likely overstates the
            velocity noise.
        mono_point_sigma_k: on a mono rig, with feature_point, the range sigma of the chosen
            feature's static point (and of its track's static member points, the units the member
            terms compare them in) is
                hypot(k sqrt(max(s2_f, chi_now)) sigma_r,f, floor r)
            (sigma_r,f its first-order sigma at the nominal ray noise feature_sigma_rad, see
            _features_batch; s2_f the feature's noise variance factor, its own fit's a-posteriori
            factor pooled with a prior of feature_noise_prior_dof dof at the nominal noise,
            ``_posterior_sigma``; chi_now its current ray's own miss over 2 sigma_f^2; floor =
            feature_range_floor_frac): k is a static point's error over the noise its own rays
            show (a KLT corner's drift over the surface is not in the residual). It replaces
            hypot(max(k, sqrt(s2_f), sqrt(chi_now)) sigma_r,f, floor r) with k =
            feature_point_sigma_k 1.9, which made a feature whose rays agree well as unsure as a
            typical one and one whose rays miss by up to k sigma_f no less sure. Renderer truth over
            one recording of dc3586f's front end (accuracy --set all; mono static-point reports:
            51-54 % of the tuned, held-out and validation sets' scored reports, 58-78 % of their
            z^2 sums), k 1.9, reports no other term widened: where k sigma_r,f > 4 floor (young or
            far features, sigma ~7 % of r) the median |error| / sigma was 0.18-0.39 (a Gaussian's
            0.674; error 2.1-2.5 % of r), their median s2_f 0.41-0.56; the reports with z^2 > 9
            had median s2_f 2.6-3.6 and chi_now 3.1-5.6, the rest 1.0-1.1 and 0.8-0.9. Default
            1.4, fitted on the tuned set with feature_noise_prior_dof: the tuned range NEES
            nearest 1 (k 1.5 / 1.4 / 1.3 at nu0 3: 0.948 / 0.998 / 1.046; nu0 0 / 3 / 10 at k 1.4:
            1.047 / 0.998 / 0.974). Narrower member points made ``_near_group_choice`` split a
            surface's relief into groups too small to anchor (held-out mono obstacle-frame
            coverage 95.39 -> 95.22 %): its agreement also spans feature_depth_gap_frac of the
            range now (see feature_near_group). Replays of that recording (accuracy --set all),
            tuned | held-out | validation | demo, before -> after both (the stereo rigs' static
            points take the same form, stereo_point_sigma_k): range NEES 0.963 -> 0.999 | 0.985
            -> 0.975 | 1.514 -> 1.508 | 1.000 -> 1.054 (every verdict as before: validation still
            FAIL, [0.97, 1.03]), median z^2 0.203 -> 0.238 | 0.169 -> 0.199 | 0.198 -> 0.225 |
            0.151 -> 0.160, 1-sigma 76.95 -> 75.32 | 77.97 -> 76.75 | 77.03 -> 76.19 | 78.34 ->
            77.18 %, z^2 > 9 1.32 -> 1.13 | 1.27 -> 0.91 | 2.14 -> 2.39 | 1.60 -> 2.03 %, mean
            without the top 1 % 0.695 -> 0.773 | 0.717 -> 0.734 | 0.870 -> 0.925 | 0.803 -> 0.855;
            mono median 1.06 -> 1.06 | 1.02 -> 1.01 | 1.18 -> 1.19 %, p90 3.02 -> 3.03 | 4.16 ->
            3.99 | 4.43 -> 4.44 %, mono obstacle-frame coverage 93.17 | 95.39 | 88.62 -> 88.66 %;
            every other target line unchanged. (The old form could not narrow the bulk: its k 1.8
            left the tuned 1-sigma at 79.1 %.) The mono static points' own median z^2 (k 1.4,
            before the near-group change) 0.223 -> 0.282 | 0.220 -> 0.283 | 0.275 -> 0.332, range
            NEES 1.262 -> 1.304 | 1.127 -> 1.081 | 2.171 -> 2.151.
        feature_noise_prior_dof: the weight (dof) of the nominal ray noise in a feature's noise
            variance factor (``_posterior_sigma``): a young feature's few rays (2n - 3 residual
            dof) lean on it. Default 3, fitted with mono_point_sigma_k (see there).
        stereo_point_sigma_k: the k of mono_point_sigma_k on a rig of two cameras or more, for
            the static-point fix (and its track's static member points, the units the member terms
            compare them in): hypot(k sqrt(max(s2_f, chi_now)) sigma_r,f, floor r). Measured below
            with the earlier form hypot(max(k, sqrt(s2_f), sqrt(chi_now)) sigma_r,f, floor r).
            feature_point_sigma_k (2.0 then) was fitted on the tuned set's NEES with the floor present
            and holds a tracked corner's offset from its surface point besides the ray noise; the
            floor (feature_range_floor_frac) is that offset, so on a stereo rig, whose static
            points rest on the baseline as well as on the flight, 2 counted it twice. Renderer
            truth over one recording of 7a24c93's front end, tuned stereo_flying: static-point
            reports (760 of its 806) had a median sigma of 2.39 % of the range against a median
            error of 0.81 % (range NEES 0.484, median z^2 0.098), and their error did not grow
            with sigma_r,f (median error 0.65 / 0.65 / 0.77 / 1.09 / 0.49 / 1.14 % of the range
            over the six sixths of sigma_r,f / r, 0.06 to 33 %): the floor's offset, not the rays'
            noise, makes it. Default 1.0, the rays' own noise measured on the tuned stereo
            renders (every member feature's two-ray point of one instant against the surface along
            its ray: median |error| over sqrt(2) sigma_f d / sin(parallax) 0.57 on stereo_flying,
            0.82 on stereo_hover, a Gaussian's 0.674: k 0.84 / 1.21). Replays of that recording
            (accuracy --set all, tuned | held-out | validation | demo), 2.0 -> 1.0: range NEES
            0.924 -> 0.954 | 1.280 -> 1.032 | 1.485 -> 1.537 | 1.018 -> 1.207 (its interval
            [0.899, 1.106]: a trade), median z^2 0.196 -> 0.208 | 0.166 -> 0.182 | 0.186 -> 0.203 |
            0.137 -> 0.206, mean without the top 1 % 0.671 -> 0.701 | 0.702 -> 0.756 | 0.850 ->
            0.899 | 0.849 -> 0.997, 1-sigma 77.34 -> 76.47 | 79.89 -> 77.46 | 77.97 -> 76.62 |
            77.71 -> 75.11 %, z^2 > 9 1.22 -> 1.22 | 1.27 -> 1.37 | 2.13 -> 2.24 | 2.60 -> 2.32 %;
            ranges nearly unchanged (the filter's state and gates take the fix's sigma: tuned
            stereo <= 8 m 1.16 -> 1.15 %, the demo's any-age p90 9.09 -> 9.29 %, info; every other
            range, coverage and speed line equal). The demo's mean now rests on
            its tail (track 46, a static point 1.5 m beyond its obstacle, carried; track 70, the
            moving box's static points). Not for the feature stereo (two-ray) fix, fused every
            frame: there the same k (same replays) moved ranges and speeds (tuned speed error
            2.71 -> 3.82 %, demo 3.23 -> 4.52 %) and the tuned NEES to 0.936.
        feature_point_quantile: which feature's point: the lower q-quantile by range of the inner
            ones. Default 0.5 (the lower median; 0.3 ranged the tracked stereo scenes better, 1.1 vs
            1.6 % within 3 m, but picked a near stray feature on a fresh tracking: NEES mean 1204).
        feature_range_floor_frac: the floor above, as a fraction of the range. Default 0.01 (the
            per-feature error stops shrinking with parallax at 1.1-1.4 % of the range: KLT corners
            drift over the surface; with the largest-depth-cluster choice and the member-spread and
            carried-state terms below, the 5 tracked pipeline scenes' range NEES median / 1-sigma
            share for floors 1.5 / 1.2 / 1.0 %: 0.24 / 79 %, 0.27 / 77 %, 0.30 / 72 %).
        feature_depth_gap_frac: with feature_point, the inner features' ranges are split into
            depth clusters where consecutive sorted ranges differ by more than this fraction, and
            only the largest cluster is ranged (``_largest_depth_cluster``; 0 = off). Default 0.3
            (tracked pipeline scenes: stereo <= 3 m median 1.41 -> 1.30 %, range NEES mean 2.86 ->
            2.72, the rest unchanged; 0.15: 1.26 % but mono coverage 92.2 -> 91.8 %).
        feature_near_group: with feature_point, on a mono rig, a track whose chosen point lies
            beyond a consistent group of its static member points (at least feature_min_count
            points, any of the track's, agreeing within 2 joint sigmas or within
            feature_depth_gap_frac of the nearer range: one surface's relief; the latter since
            mono_point_sigma_k, whose narrower sigmas split relief into groups too small to anchor;
            the relief rule alone, with the earlier sigmas, on that setting's recording: tuned |
            held-out | validation mono coverage 93.17 | 95.39 -> 95.56 | 88.62 -> 88.82 %, p90
            3.02 -> 3.03 | 4.16 -> 4.04 | 4.43 %, range NEES 0.963 | 0.985 -> 0.986 | 1.514 ->
            1.512) by more than their joint
            noise and by more than feature_depth_gap_frac of the group's range is ranged on that
            group's lower-median point instead (``_near_group_choice``): two surfaces at clearly
            different depths in one track (an obstacle grouped with one behind it, or corners
            sliding between them, e.g. T-junctions at an occluding edge), where the inner half's
            lower median fell on the far one or between them. The nearer surface is ranged (the
            safe one), and the report's bearing is its feature's, so the report describes a
            surface that is there. Default True (accuracy --set all, fusion replayed over one
            recording of 4f994d8's front end, tuned | held-out | validation | demo, off -> on: range
            NEES 0.983 -> 0.983 | 1.512 -> 1.440 | 1.751 -> 1.709 | 1.386 (unchanged); mono p90
            4.268 -> 4.157 | 4.426 -> 4.444 %, median 1.023 -> 1.015 | 1.179 -> 1.185 % (held-out |
            validation: val_moving_crossing's box at 8.7 m has ground members at 7.3 m, a nearer
            group); the rest unchanged). Not on a stereo rig (the same rule there, same replays:
            held-out stereo coverage 84.8 -> 89.5 %, <= 3 m 0.608 -> 0.435 %, but the demo's
            stereo <= 3 m 1.422 -> 1.556 %, over its 1.5 % target: 24 more reports of a track
            that had ranged a far ground point, now its sphere at 5-8 % error). Without the gap
            (0: every group beyond the noise), replays of 8ee88c1's front end: validation NEES
            1.845 -> 1.620 but tuned 0.982 -> 0.934 (below its interval), tuned mono p90 3.02 ->
            3.65 % and validation mono coverage 88.6 -> 85.8 % (ground points are a nearer group).
        feature_avoid_outline: with feature_point, a track's stereo fix is not ranged on a shared
            feature that is a vertex of the convex hull of the track's features in either view (an
            occlusion boundary: ``_outline_flags``), and "inner" (the half nearest the
            representative ray) must hold in both views (the farther of the feature's two angles),
            when two such features or more exist (else the rule is off for that track: one would
            leave the median no robustness). Default True (replays of the recorded front end,
            tuned | held-out: range NEES 1.85 -> 1.10 | 2.07 -> 2.03, median z^2 0.23 -> 0.21 |
            0.22 -> 0.18, 1-sigma 75.5 -> 77.0 | 75.6 -> 76.0 %, stereo <= 3 m median 0.89 -> 0.80 |
            1.12 -> 0.71 %, <= 8 m 1.27 -> 1.09 | 1.14 -> 0.97 %; mono, bounds and speed unchanged;
            stereo_hover's silhouette corner, 40 % of the tuned NEES sum, is no longer chosen).
            On a stereo rig (two cameras or more) it also applies to the static-point (multi-frame)
            fix's chosen feature (not on the outline of its track's features in any camera's
            view, when two inner ones or more are off it): the cameras sit off the body
            origin, so the body's ray toward a silhouette corner one camera tracks passes beside
            the obstacle (heldout_stereo_flying track 92: a point at 1.04 m on obstacle 1's edge
            seen from cam0, the body's ray toward it hits obstacle 3 at 3.85 m). Measured with the
            current-ray term of the feature's sigma (feature_point_sigma_k 2.0), replays of one
            recorded front end, tuned | held-out, without -> with both: range NEES 0.987 -> 1.010 |
            1.836 -> 1.852, median z^2 0.201 -> 0.228 | 0.187 -> 0.232, 1-sigma 78.7 -> 75.6 |
            76.8 -> 75.1 %, stereo <= 3 m (held-out) 0.64 -> 0.69 %, <= 8 m (tuned) 1.04 -> 1.06 %
            (the sigmas' shape more honest; every range target still met). Not on a mono rig: the
            same rule for a mono rig's static-point fix (the opt-in feature_avoid_outline_mono,
            removed) was a trade on replays of one recorded front end (cb37d6f's, with the occlusion
            term), tuned | validation val_* | val2_* | held-out, off -> on: mono median 1.17 ->
            1.27 | 1.17 -> 1.14 | 1.28 -> 1.26 | 1.02 -> 1.05 %, p90 3.12 -> 3.12 | 4.75 -> 4.04 |
            4.25 -> 4.04 | 4.26 -> 4.18 %, mono obstacle-frame coverage 92.97 -> 92.77 | 89.22 ->
            92.12 | 86.56 -> 86.73 | 94.71 -> 97.27 % (val2_heldout_moving 98.4 -> 94.4, val2_turning
            87.7 -> 85.3), range NEES 0.954 -> 0.981 | 2.110 -> 2.437 | 2.267 -> 2.228 | 1.790 ->
            1.714 (median z^2 0.225 -> 0.234 | 0.218 -> 0.205 | 0.241 -> 0.233 | 0.205 -> 0.205).
        carried_range_floor_frac: smallest range sigma, as a fraction of the range, of a report
            whose range no feature fix or feature stereo fix measured this frame (a state carried
            by the filter from earlier fixes and the representative bearing, a centroid that slides
            over the object; a representative-ray stereo fix). Default 0.03 (the 5 tracked pipeline
            scenes: such reports had a median error of 2.2 % of the range at a median sigma of
            1.5 %; their z^2 made 60 % of the range NEES sum).
        member_spread_weight: weight w of the member-disagreement term of the reported range sigma
            (``_member_spread``: the reported point against the median of its nearest members,
            beyond their joint noise; 0 = off). Default 1 (the sigma reaches the other estimate;
            not fitted). It replaces a spread term fitted on the tuned scenes (weight 1.5, the
            0.67-quantile of the nearest half's deviations less 0.15 r): replays of one recording
            of both sets, range NEES mean tuned 2.23 -> 1.95, held-out 2.17 -> 2.15, 1-sigma
            share 72.4 -> 75.3 %, 75.6 -> 75.4 % (errors unchanged).
        member_spread_min_n: the number of member points nearest the reported direction that
            are its neighbourhood (or all, when fewer). Default 6.
        stereo_neighbour_n: a report ranged by its feature stereo fix alone (no static-point fix
            this frame) gets a range-sigma term: the largest range disagreement beyond their joint
            noise, max_i (r_i - r)^2 - s_i^2 - var0, over this many of the track's other member
            points nearest its direction and in its depth cluster (``_stereo_neighbours``; 0 = off).
            Default 3 (the fewest that surround a direction; the tuned stereo_hover's sphere limb
            needs 3, 2 leave it).
        static_own_stereo: on a stereo rig, a report ranged by its static-point fix (one member
            feature's least-squares point over its rays of all frames and both cameras,
            ``feature_point``) whose feature also has a two-ray point this frame (its two
            cameras' rays of this instant, valid for a moving point too) gets a range-sigma term
            reaching that two-ray point beyond their joint noise (``_own_stereo``). Default True
            (the demo's moving box, track 70: static points 1-1.9 m short of the box at 5-6 m,
            sigma 0.19-0.55 m, while its features' two-ray points sat on it).
        occluder_min_members: a report whose direction from the body origin passes inside the
            angular convex hull of this many member points or more of ANOTHER track that lie nearer
            than it beyond their joint noise (``_occluded_by_members``) is hidden from the body
            origin by that track's surface: its range sigma reaches the depth of those points
            (0 = off). Default 3 (the fewest points that enclose a direction). The hull is widened
            by the tracked window's angle (ObstacleFusion's window_px, as for _window_neighbours): a nearer
            surface that comes within it reaches into the reported point's own KLT window (not
            fitted: the window's half-width, as window_px's term). Replays over the
            recorded front end of 27e4165 (accuracy --set all, tuned | held-out | validation |
            demo), without -> with the margin: range NEES 0.996 -> 0.996 | 0.963 -> 0.958 | 1.463 ->
            1.453 | 1.170 -> 1.110, 1-sigma 74.98 -> 74.98 | 77.04 -> 77.07 | 76.58 -> 76.75 |
            75.78 -> 75.78 %; with OPENBLAS_CORETYPE=Haswell 1.044 -> 1.043 | 1.060 -> 1.055 | 1.424
            -> 1.401 | 3.887 -> 3.826; ranges, coverage and speeds unchanged. It widens 2 | 10 | 53
            of the 3133 | 2953 | 11580 scored reports (validation: 5 with z^2 > 9 before, 33 below
            1). With the mono outline rule (see feature_avoid_outline) it catches val_turning track
            73 (a point at 17.7 m behind a nearer box, z^2 1858-2039) in 5 of its 6 frames.
        baseline_max_age_s: oldest sighting (s) a mono baseline / bound may use. Default 1.0.
        bounds_noise_sigmas: bearing-noise margin of the bounds, in sigmas. Default 4.0 (the angle
            between two noisy bearings exceeds 4 sqrt(2) sigma with probability exp(-8) = 3e-4;
            each ray is turned by that angle in turn, module docstring).
        bounds_pseudo_sigma_frac: sigma of the bound pseudo-measurement, as a fraction of the bound.
            Default 0.01.
        bounds_min_range_m: bounds whose upper end is below this (m) are taken as inconsistent with
            the max speed (rays that meet only at the camera), not as "the obstacle is at the
            camera" (the pseudo-measurement drove such ranges to 1e-11 m). Default 0.1.
        lost_after_s: a track not observed for this long (s) is ended (reported once as lost).
            Default 0.5.
        reinit_after_gated: consecutive gated updates after which the filter restarts. Default 5.
        member_reset_frac: a track whose member feature rays (>= 2 now and in the frame it was
            last seen) are more than this share new since that frame restarts its filter and
            sightings (the id now stands for other points; >= 1 = never). Default 0.5: a majority
            rule: the state stands for the points most of its members are (not fitted; on one
            recording of the 5 tracked pipeline scenes the range NEES mean is 3.13 / 3.17 / 3.17 /
            3.20 for 0.3 / 0.5 / 0.7 / 1 = never).
        feature_velocity_lag_s: interval (s) of the velocity measurements of stereo tracks from
            their shared features' own displacements (``_feature_velocity``; 0 = off). Default 0.1,
            the thesis's interval (sec. 3.2.2). Re-measured at 28b24bb (velocity evidence, one
            velocity per report) by replaying (a) one recording of stereo_flying, stereo_hover and
            their held-out twins and (b) an older one of demo and a 6-mover scene; moving-obstacle
            reports with a velocity, median speed / heading error: 0.1 s (a) 39 of 141, 3.0 % /
            4.3 deg, (b) 330 of 1214, 4.4 % / 1.1 deg; 0.2 s (a) 24 of 141, 1.8 % / 2.3 deg, (b)
            318 of 1219, 5.5 % / 0.8 deg; static obstacles' reported speed p90 0.10 / 0.22 m/s at
            0.1 s, 0.06 / 0.38 at 0.2 s; range errors and NEES equal within 0.02. No clear winner:
            0.1 s kept (more reports on (a); small samples).
        velocity_report_max_sigma_mps: velocity is reported only when its largest sigma (m/s) is at
            most this, and only for tracks a stereo fix has fed. Default 1.0.
        measurement_correlation_s: tau (s): a track's bearing or point update less than tau after
            its last one has its noise covariance R scaled by tau / dt (``_repeat_scale``), and a
            feature's ray less than tau after its last one counts as dt / tau of a ray in the
            static-point sums (``_FeatureRays.add``: the point's sigma_r,f, the relative-sigma gate,
            the posterior dof; the slide test's short-memory sums count each ray, a test of the
            newest rays, not a sigma); 0 = off. Consecutive measurements of the same tracked
            features share their errors, so the evidence grows per second, not per frame. Measured
            with the renderer's truth (docs/ARCHITECTURE.md, "Measurements per second at 100
            fps"): the feature bearing and stereo disparity errors' correlation is a function of
            the lag in seconds, the same at 30 and 100 fps, and lasts far longer than either frame
            interval (bearings 0.92-0.96 one 30-fps frame apart, disparities 0.65-0.74), so a
            second carries the same information at either rate; the noise settings were fitted per
            frame at 30 fps. Default 0.03, just under 1/30 s: a stream of <= 33 fps (30-fps
            timestamps k / 30 rounded to 1e-9 s included) is unchanged bit for bit; at 100 fps R
            is 3x (3.3x would be exact). The velocity measurements have their own overlap model
            (``_feature_velocity``).
    """

    max_speed_mps: float | None = None
    max_accel_mps2: float = 1.0
    accel_time_s: float = 0.1
    static_accel_mps2: float = 0.005
    static_velocity_sigma_mps: float = 0.002
    velocity_prior_sigma_mps: float | None = None
    bearing_sigma_floor_rad: float = 5e-4
    gate_probability: float = 0.999
    min_parallax_rad: float = math.radians(1.0)
    stereo_max_rel_sigma: float = 0.3
    mono_init_max_rel_sigma: float = 0.1
    feature_ranging: bool = True
    feature_sigma_rad: float = 1e-3
    feature_sigma_focal_px: float | None = 204.52395028133697
    feature_min_count: int = 3
    feature_inner_half: bool = True
    feature_static_chi: float = 9.0
    feature_static_behind: bool = True
    restart_keeps_motion: bool = True
    stereo_jump_check: bool = True
    feature_point: bool = True
    feature_max_chi: float = 36.0
    moving_mono_max_s: float = 0.3
    feature_min_depth_m: float = 0.1
    feature_point_sigma_k: float = 1.9
    mono_point_sigma_k: float = 1.4
    feature_noise_prior_dof: float = 3.0
    stereo_point_sigma_k: float = 1.0
    feature_point_quantile: float = 0.5
    feature_range_floor_frac: float = 0.01
    carried_range_floor_frac: float = 0.03
    feature_depth_gap_frac: float = 0.3
    feature_near_group: bool = True
    feature_avoid_outline: bool = True
    member_spread_weight: float = 1.0
    member_spread_min_n: int = 6
    stereo_neighbour_n: int = 3
    static_own_stereo: bool = True
    occluder_min_members: int = 3
    feature_mad_all_weight: float = 0.5
    feature_small_n_inflate: float = 1.0
    stereo_feature_min_count: int = 2
    feature_memory_s: float = 0.5
    feature_slide_memory_s: float = 0.1
    feature_ranging_moving: bool = True
    stereo_spread_weight: float = 0.6
    baseline_max_age_s: float = 1.0
    bounds_noise_sigmas: float = 4.0
    bounds_pseudo_sigma_frac: float = 0.01
    bounds_min_range_m: float = 0.1
    lost_after_s: float = 0.5
    reinit_after_gated: int = 5
    member_reset_frac: float = 0.5
    velocity_report_max_sigma_mps: float = 1.0
    feature_velocity_lag_s: float = 0.1
    measurement_correlation_s: float = 0.03

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if v is None and f.name in ("max_speed_mps", "velocity_prior_sigma_mps",
                                        "feature_sigma_focal_px"):
                continue
            if f.type == "bool":  # (2.5 or 1 is no switch: refuse, do not read it as truthy)
                if not isinstance(v, bool | np.bool_):
                    raise ConfigError(f"FusionSettings.{f.name}: expected true or false, got {v!r}")
                continue
            if isinstance(v, bool | np.bool_) or not isinstance(v, int | float) or not math.isfinite(v):
                raise ConfigError(f"FusionSettings.{f.name}: expected a finite number, got {v!r}")
            if f.type == "int" and int(v) != v:
                raise ConfigError(f"FusionSettings.{f.name}: expected an integer, got {v!r}")
            if v < 0:
                raise ConfigError(f"FusionSettings.{f.name}: expected a value >= 0, got {v!r}")
        if not 0.0 < self.gate_probability < 1.0:
            raise ConfigError(
                "FusionSettings.gate_probability: expected a probability in (0, 1), "
                f"got {self.gate_probability}"
            )
        positive = ("baseline_max_age_s", "lost_after_s", "bearing_sigma_floor_rad", "accel_time_s",
                    "bounds_pseudo_sigma_frac") + (("feature_sigma_focal_px",)
                                                   if self.feature_sigma_focal_px is not None else ())
        for name in positive:
            if getattr(self, name) <= 0:
                raise ConfigError(f"FusionSettings.{name}: expected a value > 0, got {getattr(self, name)}")
        if not 0.0 <= self.feature_point_quantile <= 1.0:
            raise ConfigError(
                "FusionSettings.feature_point_quantile: expected a quantile in [0, 1], "
                f"got {self.feature_point_quantile}"
            )
        if int(self.reinit_after_gated) != self.reinit_after_gated or self.reinit_after_gated < 1:
            raise ConfigError(
                f"FusionSettings.reinit_after_gated: expected an integer >= 1, got {self.reinit_after_gated}"
            )


def _per_camera(rig: Rig, what: str, values, ok, expected: str) -> dict[str, float]:
    """``values`` (a mapping camera name -> number, or None: {}) as floats, each checked by
    ``ok``: ObstacleFusion's per-camera keywords (pixel_scale, window_px).

    Raises InputError naming ``what`` and the camera for a key that is not one of the rig's
    cameras (a misspelt camera would leave its camera out silently), and for a value that is not a
    finite real number (a bool or a string is not one) or fails ``ok`` (``expected`` says what is).
    """
    if values is None:
        return {}
    if not isinstance(values, Mapping):
        raise InputError(f"ObstacleFusion {what}: expected a mapping camera name -> number, got {values!r}")
    out = {}
    for name, v in values.items():
        if name not in rig.names:
            raise InputError(
                f"ObstacleFusion {what}['{name}']: not a camera of the rig (expected one of "
                f"{', '.join(rig.names)})"
            )
        real = isinstance(v, int | float | np.integer | np.floating) and not isinstance(v, bool)
        x = float(v) if real else math.nan
        if not (math.isfinite(x) and ok(x)):
            raise InputError(f"ObstacleFusion {what}['{name}']: expected {expected}, got {v!r}")
        out[name] = x
    return out


def _ttangent_basis(u: tuple[float, float, float]) -> tuple[tuple, tuple]:
    """The fusion's basis of the plane orthogonal to a unit 3-tuple u, as 3-tuples of floats:
    e1 = u x e / |u x e| (e the axis least along u, the first of equal ones), e2 = u x e1 (the
    batched code's ray frames take the same basis)."""
    a0, a1, a2 = abs(u[0]), abs(u[1]), abs(u[2])
    e = (1.0, 0.0, 0.0) if a0 <= a1 and a0 <= a2 else (0.0, 1.0, 0.0) if a1 <= a2 else (0.0, 0.0, 1.0)
    e1 = _tcross(u, e)
    n = math.sqrt(_tdot(e1, e1))
    e1 = (e1[0] / n, e1[1] / n, e1[2] / n)
    return e1, _tcross(u, e1)


_EYE3 = np.eye(3)
_EYE3.setflags(write=False)
_EYE6 = np.eye(6)
_EYE6.setflags(write=False)
_H_POS = np.eye(6)[:3]  # d(position) / dx and d(velocity) / dx of the state x = [p_W, v_W]
_H_VEL = np.eye(6)[3:]
_H_POS.setflags(write=False)
_H_VEL.setflags(write=False)
_SLICE_POS, _SLICE_VEL = slice(0, 3), slice(3, 6)  # their columns of x
# filterpy's ExtendedKalmanFilter(dim_x=6, dim_z=2), built once: its constructor allocates ~20
# arrays (~40 us); a track's filter is a copy of its attributes (``_new_ekf``), whose arrays the
# fusion never writes in place (x and P are the filter's own; the update binds new S, SI, K, y,
# x, P; predict binds the shared read-only F, Q), so the template's are made read-only
_EKF_TEMPLATE = ExtendedKalmanFilter(dim_x=6, dim_z=2)
for _a in vars(_EKF_TEMPLATE).values():
    if isinstance(_a, np.ndarray):
        _a.setflags(write=False)


def _new_ekf() -> ExtendedKalmanFilter:
    """A filterpy ExtendedKalmanFilter(dim_x=6, dim_z=2) sharing the template's read-only initial
    arrays (its x and P to be bound by the caller), without the constructor's allocations."""
    kf = object.__new__(ExtendedKalmanFilter)
    kf.__dict__.update(_EKF_TEMPLATE.__dict__)
    return kf


_CHI2_PPF: dict[tuple[float, int], float] = {}  # (probability, dof) -> chi2_ppf, ``_chi2_gate``


def _nearest_per_group(g: np.ndarray, cos: np.ndarray, G: int, n: int) -> np.ndarray:
    """Indices (into g) of each group's n members of largest cos (fewer when a group has fewer),
    for groups g (K,) in [0, G) and cosines cos (K,) of each member's direction to its group's
    reported direction: the n nearest in direction, ties by index."""
    order = np.lexsort((-cos, g))  # by group, nearest the reported direction first
    cnt = np.bincount(g, minlength=G)
    start = cnt.cumsum() - cnt
    return order[np.arange(len(order)) - start[g[order]] < n]


def _group_lower_median_index(g: np.ndarray, v: np.ndarray, cnt: np.ndarray, q: float = 0.5) -> np.ndarray:
    """Index into v (K,) of the lower q-quantile (default the lower median) of each non-empty group
    g (K,) (cnt (G,) = the group sizes): element floor((n - 1) q) of the group sorted by v ->
    (number of non-empty groups,), in group order."""
    order = np.lexsort((v, g))
    start = cnt.cumsum() - cnt
    nz = cnt > 0
    return order[start[nz] + np.floor((cnt[nz] - 1) * q + 1e-9).astype(np.int64)]


def _near_group_choice(g: np.ndarray, r: np.ndarray, s: np.ndarray, pick: np.ndarray, n_min: int,
                       gap_frac: float, z: float = 2.0) -> np.ndarray:
    """Each track's chosen point moved to its nearest consistent group: indices into r like pick.

    g (K,) track index of each of the tracks' static member points, r (K,) its range from the
    body origin (m), s (K,) its range sigma in the reports' units (m); pick (T,) the index of each
    ranged track's current choice (at most one per track). Two points agree when they are one
    surface: within their joint noise or within the depth a surface may span (gap_frac of the
    nearer range, ``_largest_depth_cluster``'s split),
        |r_i - r_j| <= max(z sqrt(s_i^2 + s_j^2), gap_frac min(r_i, r_j))
    (with the noise alone, a surface's relief beyond its points' sigmas split it into groups too
    small to anchor: 4 points at 7.52-7.83 m with sigmas ~0.05 m). A track's near anchor is its
    nearest point that n_min points (itself included) agree with; its near group is those points,
    and the group's lower
    median (by range) replaces the current choice c when it lies beyond it by more than their
    joint noise and by more than gap_frac of its range (two surfaces, not one surface's depth):
        r_c - r_near > max(z sqrt(s_c^2 + s_near^2), gap_frac r_near)
    (the members disagree: two surfaces at different depths in one track, or points sliding
    between them; the nearer surface is ranged, and the report's bearing is its feature's)."""
    out = pick.copy()
    if len(g) == 0 or len(pick) == 0 or n_min < 1:
        return out
    # only a track whose choice lies that far beyond its NEAREST point can move (the group's
    # median lies at or beyond it): the others are left before the pairwise work
    order = np.lexsort((r, g))  # by track, then range
    g_sorted = g[order]
    cnt = np.bincount(g_sorted)
    r_min = np.full(len(cnt), np.inf)
    r_min[cnt > 0] = r[order[(cnt.cumsum() - cnt)[cnt > 0]]]
    rm = r_min[g[pick]]
    live = r[pick] - rm > np.maximum(z * s[pick], gap_frac * rm)
    if not live.any():
        return out
    tracks_live = np.zeros(len(cnt), dtype=bool)
    tracks_live[g[pick[live]]] = True
    order = order[tracks_live[g_sorted]]  # the points of those tracks, still sorted
    K = len(order)
    gs, rs, ss = g[order], r[order], s[order]
    cnt = np.bincount(gs)
    start = cnt.cumsum() - cnt
    # every ordered pair (i, j) of points of one track (positions in the sorted order)
    n_i = cnt[gs]
    off = n_i.cumsum() - n_i  # i's pairs are ii[off[i]:off[i] + n_i[i]]
    ii = np.arange(K).repeat(n_i)
    jj = start[gs][ii] + (np.arange(len(ii)) - off[ii])
    agree = np.abs(rs[ii] - rs[jj]) <= np.maximum(z * np.sqrt(ss[ii] ** 2 + ss[jj] ** 2),
                                                  gap_frac * np.minimum(rs[ii], rs[jj]))
    support = np.bincount(ii[agree], minlength=K)  # points agreeing with i (itself included)
    # the nearest anchor of each track (within a track the sorted order is by range)
    first = np.full(len(cnt), -1, dtype=np.int64)
    a_idx = (support >= n_min).nonzero()[0]  # (ascending: by track, then range)
    # each track's first anchor (np.unique's index of first occurrence; an assignment through
    # repeated indices has no guaranteed order in numpy)
    g_a, at = _unique_first(gs[a_idx])
    first[g_a] = a_idx[at]
    a_pick = np.full(len(pick), -1, dtype=np.int64)
    a_pick[live] = first[g[pick[live]]]
    # (and beyond its anchor likewise)
    r_a = rs[np.maximum(a_pick, 0)]
    due = ((a_pick >= 0) & (r[pick] - r_a > np.maximum(z * s[pick], gap_frac * r_a))).nonzero()[0]
    for m in due.tolist():
        c, a = int(pick[m]), int(a_pick[m])
        sl = slice(off[a], off[a] + n_i[a])
        grp = jj[sl][agree[sl]]  # positions agreeing with the anchor, in range order
        near = int(grp[(len(grp) - 1) // 2])  # the group's lower median
        if r[c] - rs[near] > max(z * math.sqrt(s[c] ** 2 + ss[near] ** 2), gap_frac * rs[near]):
            out[m] = order[near]
    return out


def _report_members(parts) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """This frame's member points of the reports' tracks, from member sets in the given order.

    parts: pairs (members, j_of_group): members ``(g (M,) group index, r (M,) range from the body
    origin m, b (M, 3) unit direction in W from the body origin, s (M,) range sigma m in the
    reports' units)`` (``_members_ls``, ``_members_st``) or None; j_of_group (G,) int the report
    index of each group's track, -1 for a group whose points are not wanted. Returns (jj, r, b, s)
    of the wanted points (jj (N,) report index), the parts' points in order, or None when there
    are none (N = 0)."""
    jj_l, r_l, b_l, s_l = [], [], [], []
    for mem, jmap in parts:
        if mem is None or not len(mem[0]):
            continue
        jj = jmap[mem[0]]
        m = jj >= 0
        jj_l.append(jj[m])
        r_l.append(mem[1][m])
        b_l.append(mem[2][m])
        s_l.append(mem[3][m])
    if not jj_l:
        return None
    if len(jj_l) == 1:
        jj, r, b, sr = jj_l[0], r_l[0], b_l[0], s_l[0]
    else:
        jj, r, b, sr = np.concatenate(jj_l), np.concatenate(r_l), np.concatenate(b_l), np.concatenate(s_l)
    if not len(jj):
        return None
    return jj, r, b, sr


_NO_FEATURES = np.zeros((0, 3))
_NO_FEATURES.setflags(write=False)
_NO_IDS = np.zeros(0, dtype=np.int64)
_NO_IDS.setflags(write=False)


class _View:
    """One camera's sighting in W: centre c_W (3,) m, unit bearing b_W (3,), sigma (rad), and the
    member features: feature_ids (M,) and their unit bearings feature_b_W (M, 3). (A slotted class,
    not a frozen dataclass: one is built per track and camera each frame.)"""

    __slots__ = ("camera", "c_W", "b_W", "sigma_rad", "feature_ids", "feature_b_W")

    def __init__(self, camera: str, c_W: np.ndarray, b_W: np.ndarray, sigma_rad: float,
                 feature_ids: np.ndarray = _NO_IDS, feature_b_W: np.ndarray = _NO_FEATURES) -> None:
        self.camera = camera
        self.c_W = c_W
        self.b_W = b_W
        self.sigma_rad = sigma_rad
        self.feature_ids = feature_ids
        self.feature_b_W = feature_b_W


class _FeatureRays:
    """Multi-view triangulation of member features (static points), shared by all tracks of a run.

    Feature ids are physical-point ids (ARCHITECTURE.md): every ray with one id, from any camera at
    any time, belongs to one point. For feature f with rays (c_i, b_i) the least-squares point
    minimises sum_i |(I - b_i b_i^T)(p - c_i)|^2 (squared perpendicular distances), i.e. A_f p = y_f
    with the running sums (normal equations, updated incrementally: one ray costs O(1))
        A_f = sum_i (I - b_i b_i^T),   y_f = sum_i (I - b_i b_i^T) c_i
    (the midpoint of two rays generalised to N). Rows live in preallocated arrays (capacity doubles)
    and are compacted when features have been unseen for ``max_unseen_s``.
    """

    def __init__(self, capacity: int = 1024) -> None:
        self.ids = np.zeros(0, dtype=np.int64)  # known feature ids, sorted
        self.id_rows = np.zeros(0, dtype=np.int64)  # their rows
        self.size = 0
        self.b0 = np.zeros((capacity, 3))  # first bearing (parallax reference)
        self.last_t = np.zeros(capacity)
        self._set_sums(np.zeros((capacity, 18)))
        # the same sums with a short memory (``add``'s short_memory_s): the newest rays' own point,
        # for the slide test (``_slid_features``); unused (zeros) when that memory is 0
        self.S_new = np.zeros((capacity, 18))

    def _set_sums(self, S: np.ndarray) -> None:
        """Bind the running sums S (capacity, 18), each row's side by side (``add`` gathers and
        scatters a row once), and their views: A (cap, 3, 3), y (cap, 3), bc (cap, 3) = sum_i b_i
        (b_i . c_i) (for the rays' depths), cc (cap,) = sum_i c_i^T (I - b_i b_i^T) c_i (for the
        residual), n (cap,) = rays so far; column 16 (no view, read as S[:, 16] by ``_depth2``) =
        sum_i (b_i . c_i)^2."""
        self.S = S
        self.A = S[:, 0:9].reshape(len(S), 3, 3)
        self.y = S[:, 9:12]
        self.bc = S[:, 12:15]
        self.cc = S[:, 15]
        self.n = S[:, 17]

    def _grow(self, need: int) -> None:
        cap = len(self.n)
        if need <= cap:
            return
        new = max(need, 2 * cap)
        for name in ("b0", "last_t"):
            a = getattr(self, name)
            b = np.zeros((new,) + a.shape[1:])
            b[: self.size] = a[: self.size]
            setattr(self, name, b)
        S = np.zeros((new, self.S.shape[1]))
        S[: self.size] = self.S[: self.size]
        self._set_sums(S)
        S_new = np.zeros((new, self.S_new.shape[1]))
        S_new[: self.size] = self.S_new[: self.size]
        self.S_new = S_new

    def rows(self, ids: np.ndarray, b_W: np.ndarray) -> np.ndarray:
        """Row of each feature id (M,), allocating rows (first bearing b_W (M, 3)) for new ids, in
        the order of their first appearance (an id can repeat within one call: several cameras)."""
        known = self.ids
        if len(known):
            pos = np.minimum(known.searchsorted(ids), len(known) - 1)
            found = known[pos] == ids
            rows = np.where(found, self.id_rows[pos], -1)
        else:
            found = np.zeros(len(ids), dtype=bool)
            rows = np.full(len(ids), -1, dtype=np.int64)
        new = (~found).nonzero()[0]
        if len(new):
            uniq, first, inv = np.unique(ids[new], return_index=True, return_inverse=True)
            rank = np.empty(len(uniq), dtype=np.int64)
            rank[first.argsort(kind="stable")] = np.arange(len(uniq))
            r_new = self.size + rank  # row of each new id (by first appearance)
            self._grow(self.size + len(uniq))
            self.b0[r_new] = b_W.take(new[first], 0)
            self.S[r_new] = 0.0  # (rows past size may hold compacted-away data)
            self.S_new[r_new] = 0.0
            self.size += len(uniq)
            rows[new] = r_new[inv.reshape(-1)]
            all_ids = np.concatenate([known, uniq])
            all_rows = np.concatenate([self.id_rows, r_new])
            order = all_ids.argsort(kind="stable")
            self.ids, self.id_rows = all_ids[order], all_rows[order]
        return rows

    def add(
        self, rows: np.ndarray, b_W: np.ndarray, c_W: np.ndarray, t_s: float, memory_s: float = 0.0,
        unique: bool = False, short_memory_s: float = 0.0, correlation_s: float = 0.0,
    ) -> None:
        """Add one ray per entry: rows (M,), unit bearings b_W (M, 3), centres c_W (M, 3), in W, at
        t_s (s); ``unique``: the caller knows the rows are distinct (no search for repeated rows).
        memory_s > 0 first scales the rows' sums by exp(-(t_s - t_last) / memory_s)
        (exponential forgetting: a tracked corner drifts over the object, so old rays stop meeting
        the point it tracks now). short_memory_s > 0 also keeps the sums ``S_new`` forgetting with
        that time constant (the newest rays' point). correlation_s > 0: a row's ray less than
        correlation_s after its last one enters the long-memory sums with weight dt / correlation_s
        (FusionSettings.measurement_correlation_s; a new row's first ray 1), the short-memory ones
        with 1."""
        M = len(rows)
        if not M:
            return
        Pm = np.eye(3)[None] - b_W[:, :, None] * b_W[:, None, :]  # I - b b^T, (M, 3, 3)
        Pc = _einsum("kij,kj->ki", Pm, c_W)
        cPc = np.sum(Pc * c_W, axis=1)
        bdc = np.sum(b_W * c_W, axis=1)  # b_i . c_i
        bbc = b_W * bdc[:, None]
        # each ray's terms in the sums' layout (``_set_sums``): A, y, bc, cc, bcc, n
        new = np.concatenate((Pm.reshape(M, 9), Pc, bbc, cPc[:, None], (bdc * bdc)[:, None],
                              np.ones((M, 1))), axis=1)
        new_s = new  # (the short memory's rays: counted one each)
        if correlation_s > 0:  # a row's ray within correlation_s of its last one counts as
            # dt / correlation_s of a ray (its error is mostly the last ray's; a new row's: 1)
            w = np.where(self.n[rows] > 0, np.minimum((t_s - self.last_t[rows]) / correlation_s, 1.0), 1.0)
            if (w < 1.0).any():
                new = new * w[:, None]
        S = self.S
        rest = None
        if not unique:  # a row repeated (a feature's rays from several cameras): the sums take
            # its rays in call order (np.add.at's): the first of every row, then the second ones...
            order = rows.argsort(kind="stable")
            rs = rows[order]
            brk = np.ones(M, dtype=bool)
            np.not_equal(rs[1:], rs[:-1], out=brk[1:])
            if not brk.all():
                start = brk.nonzero()[0]
                rank = np.arange(M) - start.repeat(np.diff(np.append(start, M)))
                rest = (order, rank)
                first = order[brk]
                rows_all, new_all, new_s_all = rows, new, new_s
                rows, new, new_s = rows[first], new.take(first, 0), new_s.take(first, 0)
        if short_memory_s > 0:  # (before last_t moves) the same rays with the short memory
            f = np.exp(-(t_s - self.last_t[rows]) / short_memory_s)
            self.S_new[rows] = self.S_new.take(rows, 0) * f[:, None] + new_s
        if memory_s > 0:  # forget old rays, w = exp(-(t_s - t_last) / memory_s): w s + new
            f = np.exp(-(t_s - self.last_t[rows]) / memory_s)
            S[rows] = S.take(rows, 0) * f[:, None] + new
        else:
            S[rows] += new
        if rest is not None:
            order, rank = rest
            for k in range(1, int(rank.max()) + 1):
                sel = order[rank == k]
                S[rows_all[sel]] += new_all[sel]
                if short_memory_s > 0:
                    self.S_new[rows_all[sel]] += new_s_all[sel]
        self.last_t[rows] = t_s

    def prune(self, t_s: float, max_unseen_s: float) -> None:
        """Drop features unseen for longer than max_unseen_s (compacts when a quarter is dead)."""
        keep = t_s - self.last_t[: self.size] <= max_unseen_s
        if 4 * int((~keep).sum()) < self.size:
            return
        remap = -np.ones(self.size, dtype=np.int64)
        remap[keep] = np.arange(int(keep.sum()))
        r = remap[self.id_rows]
        alive = r >= 0
        self.ids, self.id_rows = self.ids[alive], r[alive]
        m = int(keep.sum())
        for a in (self.S, self.S_new, self.b0, self.last_t):
            a[:m] = a[: self.size][keep]
        self.size = m


def _pAp(S: np.ndarray, p: np.ndarray) -> np.ndarray:
    """p^T A p (K,) of points p (K, 3) with the A of the feature store's sum rows S (K, 18)."""
    return _einsum("ki,kij,kj->k", p, S[:, 0:9].reshape(len(S), 3, 3), p)


def _residual2(S: np.ndarray, p: np.ndarray, pAp: np.ndarray) -> np.ndarray:
    """Mean squared perpendicular miss (m^2) of each feature's rays from its point p (K, 3), from
    its ``_FeatureRays`` sum rows S (K, 18) and p^T A p (K,): (p^T A p - 2 p^T y + cc) / n."""
    cost = pAp - 2.0 * np.sum(p * S[:, 9:12], axis=1) + S[:, 15]
    return np.maximum(cost, 0.0) / np.maximum(S[:, 17], 1.0)


def _depth2(S: np.ndarray, p: np.ndarray, pAp: np.ndarray) -> np.ndarray:
    """Mean squared depth (m^2) of each feature's point p (K, 3) along its own rays, with the rays'
    (forgetting) weights w_i: sum_i w_i (b_i . (p - c_i))^2 / sum_i w_i, from its ``_FeatureRays``
    sum rows S (K, 18) and p^T A p (K,) as (p^T B p - 2 p . e + f) / n with B = sum_i w_i b_i b_i^T
    = n I - A, e = sum_i w_i b_i (b_i . c_i) and f = sum_i w_i (b_i . c_i)^2."""
    n = S[:, 17]
    s = n * np.sum(p * p, axis=1) - pAp - 2.0 * np.sum(p * S[:, 12:15], axis=1) + S[:, 16]
    return np.maximum(s, 0.0) / np.maximum(n, 1e-12)


def _largest_depth_cluster(g: np.ndarray, r: np.ndarray, m: np.ndarray, gap_frac: float) -> np.ndarray:
    """Mask (K,) of the entries of each group's largest depth cluster among the entries m (K,)
    (bool): a group's ranges r (K,) sorted ascending split where one exceeds the previous by more
    than gap_frac of it (r_(i+1) > (1 + gap_frac) r_i); the cluster with the most entries is kept
    (of equal ones the nearest). Members of another object or of the background behind a track's
    obstacle form their own clusters and drop out before the median."""
    idx = m.nonzero()[0]
    out = np.zeros(len(g), dtype=bool)
    if not len(idx):
        return out
    gm, rm = g[idx], r[idx]
    order = np.lexsort((rm, gm))
    gs, rs = gm[order], rm[order]
    brk = np.ones(len(gs), dtype=bool)
    brk[1:] = (gs[1:] != gs[:-1]) | (rs[1:] > (1.0 + gap_frac) * rs[:-1])
    cl = brk.cumsum() - 1  # cluster id, clusters in (group, range) order
    size = np.bincount(cl)
    cg = gs[brk]  # group of each cluster
    # per group the first cluster of the largest size: sort clusters by (group, -size, id)
    best = np.lexsort((np.arange(len(size)), -size, cg))
    first = np.ones(len(best), dtype=bool)
    first[1:] = cg[best[1:]] != cg[best[:-1]]
    keep_cl = np.zeros(len(size), dtype=bool)
    keep_cl[best[first]] = True
    out[idx[order[keep_cl[cl]]]] = True
    return out


def _outline_flags(b_W: np.ndarray, view: np.ndarray) -> np.ndarray:
    """Mask (M,) of the member features on the outline of their view's features: the vertices of
    the convex hull of each view's feature bearings.

    b_W (M, 3): unit feature bearings in W; view (M,) int: the view (track and camera) of each,
    one view's entries consecutive. Each view's bearings are projected onto the plane
    tangent to their mean direction m (gnomonic, p = (b.e1, b.e2) / b.m: straight lines stay
    straight, so the hull is the image's up to the lens's local distortion) and cv2.convexHull
    gives the hull's vertices. Views of at most 3 features are all outline. Model (occlusion
    boundaries): a track's outline is where its object meets what lies behind it; a corner there
    is often a T-junction of the object's edge and a farther surface (or sky), or a silhouette
    that is a different edge from each viewpoint (a box's front edge from one camera, its back
    edge from the other), not one physical point: the two cameras of a rig see different points
    (a stereo fix short or long of the surface, often in front of nothing) while the fit of its
    rays can stay good (rays in one plane with the baseline always meet). Interior corners have
    the object on every side.
    """
    import cv2  # (the core OpenCV dependency; imported here: the fusion's only use)

    M = len(view)
    out = np.zeros(M, dtype=bool)
    if M == 0:
        return out
    start = np.diff(view, prepend=view[0] - 1).nonzero()[0]
    cnt = np.diff(np.append(start, M))
    out[(cnt <= 3).repeat(cnt)] = True
    big = cnt > 3
    if not big.any():
        return out
    idx = big.repeat(cnt).nonzero()[0]  # the rows of the views to test
    nb = cnt[big]
    sb = nb.cumsum() - nb  # their views' starts in idx
    B = b_W[idx]
    m = np.add.reduceat(B, sb, axis=0)
    m /= np.sqrt(_dot_rows(m, m))[:, None]
    e = np.zeros_like(m)  # the axis least along m, crossed with m: e1 and e2 = m x e1
    e[np.arange(len(m)), np.argmin(np.abs(m), axis=1)] = 1.0
    e1 = _cross(m, e)
    e1 /= np.sqrt(_dot_rows(e1, e1))[:, None]
    e2 = _cross(m, e1)
    vid = np.arange(len(m)).repeat(nb)
    den = np.maximum(_dot_rows(B, m[vid]), 1e-9)
    P = np.stack([_dot_rows(B, e1[vid]), _dot_rows(B, e2[vid])], axis=1) / den[:, None]
    P = P.astype(np.float32)  # (cv2.convexHull takes 32-bit points)
    hull = cv2.convexHull
    hits = [hull(P[a:a + n], returnPoints=False) for a, n in zip(sb.tolist(), nb.tolist(), strict=True)]
    lens = [len(h) for h in hits]
    out[idx[np.concatenate(hits).ravel() + sb.repeat(lens)]] = True
    return out


def _polar_enclosed(ang: np.ndarray, grp: np.ndarray, n: int) -> np.ndarray:
    """Mask (n,): the groups grp (K,) in [0, n) whose points, at polar angles ang (K,) rad about
    an origin, enclose it: no half-plane through the origin holds them all, i.e. the largest gap
    between their sorted angles (with the wrap) is below pi (False for an empty group)."""
    if not len(ang):
        return np.zeros(n, dtype=bool)
    order = np.lexsort((ang, grp))
    a_s, q_s = ang[order], grp[order]
    cnt = np.bincount(grp, minlength=n)
    start = cnt.cumsum() - cnt
    gaps = a_s[1:] - a_s[:-1]
    gaps[q_s[1:] != q_s[:-1]] = 0.0  # (no gap across groups)
    gmax = np.zeros(n)
    if len(gaps):
        np.maximum.at(gmax, q_s[1:], gaps)
    last = start + cnt - 1  # (an empty group's -1 or len: clamped below, masked by cnt > 0)
    wrap = a_s[np.minimum(start, len(a_s) - 1)] + 2.0 * math.pi - a_s[np.minimum(last, len(a_s) - 1)]
    return (cnt > 0) & (np.maximum(gmax, wrap) < math.pi)


def _unique_first(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(keys, return_index=True)`` of integer keys (N,): the sorted distinct keys and the
    index of each one's first occurrence, the same arrays by np.unique's own steps (a stable argsort,
    then each sorted key unlike the one before it), without its overhead (11 us against 16 on a few
    hundred keys)."""
    order = keys.argsort(kind="stable")
    ks = keys[order]
    new = np.empty(len(ks), dtype=bool)
    new[:1] = True
    np.not_equal(ks[1:], ks[:-1], out=new[1:])
    return ks[new], order[new]


def _group_median(g: np.ndarray, v: np.ndarray, n_groups: int) -> np.ndarray:
    """Median of v (K,) within each group g (K,) in [0, n_groups) -> (n_groups,), 0 for empty groups
    (the mean of the two middle values for even counts, as np.median)."""
    if len(v) == 0:
        return np.zeros(n_groups)
    order = np.lexsort((v, g))
    vs = v[order]
    cnt = np.bincount(g, minlength=n_groups)
    start = cnt.cumsum() - cnt
    lo = np.minimum(start + np.maximum(cnt - 1, 0) // 2, len(v) - 1)
    hi = np.minimum(start + cnt // 2, len(v) - 1)
    return np.where(cnt > 0, 0.5 * (vs[lo] + vs[hi]), 0.0)


class _Bounds:
    """A track's moving-obstacle range interval this frame (m, from the body origin; range_max_m
    None = unbounded): the fields of geometry.RangeBounds the fusion reads, in a slotted class."""

    __slots__ = ("range_min_m", "range_max_m")

    def __init__(self, range_min_m: float, range_max_m: float | None) -> None:
        self.range_min_m = range_min_m
        self.range_max_m = range_max_m


class _FrameContext:
    """What every track's report of one frame shares: T_W_B's inverse rotation R_B_W (3, 3), the
    body origin o_W (3,) m and the drone's velocity v_drone_W (3,) m/s, in W."""

    __slots__ = ("R_B_W", "o_W", "v_drone_W", "t_s")

    def __init__(self, T_W_B: Pose, v_drone_W: np.ndarray, t_s: float = 0.0) -> None:
        self.t_s = t_s
        self.R_B_W = T_W_B.R.T
        self.o_W = T_W_B.t
        self.v_drone_W = np.asarray(v_drone_W, dtype=float)


class _Sighting:
    """One track's views of one frame: t_s (s), frame index, body origin o_W (3,) m in W at t_s,
    views (one _View per camera, in the rig's order), c0 (the first view's centre as a 3-tuple of
    floats, for baseline searches) and f0 (each view's offset in the frame's feature arrays)."""

    __slots__ = ("t_s", "frame", "o_W", "views", "c0", "f0")

    def __init__(self, t_s: float, frame: int, o_W: np.ndarray, views: tuple[_View, ...],
                 c0: tuple[float, float, float] | None = None, f0: tuple[int, ...] = ()) -> None:
        self.t_s = t_s
        self.frame = frame
        self.o_W = o_W
        self.views = views
        self.c0 = c0 if c0 is not None else tuple(views[0].c_W.tolist())
        self.f0 = f0


@dataclass
class _Track:
    id: int
    label: str
    history: deque = field(default_factory=deque)  # of _Sighting, oldest first
    kf: ExtendedKalmanFilter | None = None
    t_kf: float = 0.0  # time of the filter state
    moving: bool = False  # a stereo fix has fed it: moving hypothesis, velocity observable
    sources: set = field(default_factory=set)
    gated: int = 0
    gated_run: int = 0
    nis: float | None = None
    innovation: np.ndarray | None = None
    last_seen_t: float = 0.0
    last_views: tuple[_View, ...] = ()
    cameras: tuple[str, ...] = ()
    bounds: _Bounds | None = None
    bounds_reason: str | None = None
    reason: str | None = None
    bounded_now: bool = False
    attributes: dict = field(default_factory=dict)
    feature_range: tuple[float, float, int] | None = None  # (range, sigma, n features) this frame
    feature_stereo: tuple[float, float, int] | None = None  # stereo range from common features
    struct_sigma_m: float = 0.0  # features' spread about the representative ray (not filtered)
    feature_point: np.ndarray | None = None  # the median member feature's own point (W), this frame
    feature_point_fid: int | None = None  # that feature's id, this frame
    point_fid: int | None = None  # the member feature whose point the static state is (support)
    point_is_feature: bool = False  # the state was set at that feature's own point (feature_point)
    feature_stereo_point: np.ndarray | None = None  # the median shared feature's stereo point (W)
    feature_stereo_fid: int | None = None  # the id of that feature (kept while it stays an inner one)
    feature_stereo_anchor: bool = False  # the filter's position is on another point: re-anchor it
    t_ranged: float = -math.inf  # last time a range measurement (stereo, features) fed the state
    vel_ref: list | None = None  # references, oldest first: (t_s, shared feature ids (sorted), their
    # two-ray points (K, 3) W, sigmas along / across the ray (K,), ray directions (K, 3))
    feature_velocity: tuple | None = None  # (v_W (3,), R (3, 3)) measured this frame, or None
    vel_moving: bool = False  # its velocity evidence rejects zero (not a static obstacle)
    vel_acc: tuple | None = None  # velocity evidence (v (3,), P (3, 3), t_s) from feature velocities
    motion_carry: tuple | None = None  # ((v, P, t_s), ...): the obstacle's velocities measured before a
    # member-replacement restart that rejected zero then (``restart_keeps_motion``)
    vel_assumed: bool = False  # the state's velocity is the prior's (state replaced), not measured
    n_members: int = 0  # member feature rays (all views) in the last frame it was seen
    t_members: float = -math.inf  # time of that frame
    member_ids: np.ndarray | None = None  # their feature ids (a view of that frame's id array)
    # a state a mono triangulation of two representative bearings set (``_init_mono``): whether a
    # bearing it was not triangulated from has tested it and its latest test passed (None: another
    # state, set by feature points or stereo)
    pair_tested: bool | None = None


class ObstacleFusion:
    """Per-obstacle EKFs over a run: ``step`` once per frame with the front end's observations.

    Args:
        rig: the cameras (names, models, ``T_C_B`` mounts).
        egomotion: ``T_W_B(t_s)`` and the drone's velocity; times it does not cover raise InputError.
        settings: :class:`FusionSettings`.
        pixel_scale: per camera name, the scale of the images its features are tracked in (the
            front end's ``FrontEnd.scale``, ``trackers.frontend.tracked_scale``: a frame wider than
            its max_width is tracked downscaled); None or a missing camera: 1, the full frame. The
            settings' pixel quantities (feature_sigma_focal_px's f) and window_px are of tracked
            pixels, so a rig's px per rad is taken at that scale. InputError for a name that is not
            one of the rig's cameras or a value that is not a real number in (0, 1] (a bool is not).
        window_px: per camera name, the full width (tracked px, see pixel_scale) of the KLT window its
            features are tracked by (the front end's ``features.win_px``: the FeatureTracker's temporal
            window and the stereo KLT's; ``trackers.frontend.tracked_window``). A report ranged by a
            member feature's static point (``feature_point``) gets a range-sigma term when a static member
            point of this frame (any track's) lies within the tracked window's angle of its direction at
            another depth beyond their joint noise: max_i (r_i - r)^2 - s_i^2 - var0
            (``_window_neighbours``). The angle is the window's half-width over the camera's px per rad at
            its tracked scale (as feature_sigma_focal_px's f; the largest over the cameras): a window that
            holds a second surface (a T-junction of a near outline and a farther surface, a curved
            obstacle's limb, a point a nearer obstacle is passing) moves with a blend of two parallaxes,
            which on a mono rig fits a static point at a wrong depth as well as a real point fits its own
            (renderer truth over tuned/held-out/validation mono_straight-family scenes and
            thesis_speed_15mps: the chosen feature's chi, its rays' spread across their epipolar plane and
            its short-memory slide statistic do not separate the reports with z^2 > 25 from the rest).
            None (or no camera): no window term, for rays not tracked by a window (synthetic bearings).
            InputError, as for pixel_scale, for a name not of the rig or a value not a real number > 0.
            Not fitted: the window's half-width. As the former FusionSettings.feature_window_px 5.5 (the
            11-px window's half-width, set by hand; removed: it did not follow win_px): replays over one
            recording of 7ca8491's front end (accuracy --set all, tuned | held-out | validation | demo),
            off -> on: range NEES 0.944 -> 0.924 | 1.416 -> 1.280 | 1.660 -> 1.485 | 1.018, median z^2
            0.208 -> 0.196 | 0.186 -> 0.166 | 0.207 -> 0.186, z^2 > 9 1.32 -> 1.22 | 1.41 -> 1.27 | 2.69
            -> 2.13 %, 1-sigma 76.92 -> 77.34 | 78.59 -> 79.89 | 76.23 -> 77.97 %; ranges, coverage and
            (the term then on mono rigs only) stereo rigs unchanged. The tuned NEES, already below its
            interval (0.951), moves further below: a trade. On stereo rigs too (with stereo_point_sigma_k
            1.0; replays over one recording of 7a24c93's front end, tuned | held-out | validation | demo,
            mono only -> every rig): range NEES 0.954 -> 0.940 | 1.032 -> 0.983 | 1.537 -> 1.491 | 1.207
            -> 1.006 (in its interval again: the demo's moving box, track 70, and 5 of its reports with
            z^2 > 9 are caught), median z^2 0.208 -> 0.196 | 0.182 -> 0.166 | 0.203 -> 0.192 | 0.206 ->
            0.153, z^2 > 9 1.22 -> 1.22 | 1.37 -> 1.34 | 2.24 -> 2.15 | 2.32 -> 1.59 %, 1-sigma 76.47 ->
            77.24 | 77.46 -> 78.38 | 76.62 -> 77.49 | 75.11 -> 77.57 %; ranges unchanged. It widens 11-16
            % of the stereo scenes' reports (tuned stereo_flying 129 of 806, none of them with z^2 > 9
            without it; held-out stereo_flying 105 of 946, one): a trade of the bulk's width for the
            demo's and held-out's tails.

    Attributes:
        timings: the last step's seconds in ``estimate`` (triangulations, bounds) and ``fuse`` (filters).
    """

    def __init__(
        self,
        rig: Rig,
        egomotion: EgoMotion,
        settings: FusionSettings | None = None,
        pixel_scale: Mapping[str, float] | None = None,
        window_px: Mapping[str, float] | None = None,
    ):
        self.rig = rig
        self.egomotion = egomotion
        s = settings or FusionSettings()
        scale = _per_camera(rig, "pixel_scale", pixel_scale, lambda k: 0.0 < k <= 1.0,
                            "the scale of the images the features are tracked in, in (0, 1]")
        win = _per_camera(rig, "window_px", window_px, lambda w: w > 0.0,
                          "the width of the KLT window the features are tracked by, in tracked px > 0")
        f_ref = s.feature_sigma_focal_px
        f_rig = None
        # f: px per rad at the image centre, d uv / d b_C on the optical axis (fx, fy for
        # Equidistant; fx / (1 + xi) for DoubleSphere), of the images the features are tracked
        # in (a frame wider than the front end's max_width is tracked downscaled: pixel_scale)
        axis = np.array([[0.0, 0.0, 1.0]])
        f_cam = {c.name: float(np.min(np.abs(np.diagonal(c.model.bearing_to_pixel_jacobian(axis)[0]))))
                 * scale.get(c.name, 1.0) for c in rig}
        if f_cam:
            f_rig = min(f_cam.values())
        # a feature's error is a pixel error (see the setting)
        if f_ref is not None and f_rig is not None and f_rig < f_ref * (1.0 - 1e-9):
            # (rounding of the Jacobian: equal focal lengths stay equal)
            s = replace(s, feature_sigma_rad=s.feature_sigma_rad * (f_ref / f_rig))
        self.settings = s  # (feature_sigma_rad: the rig's own)
        # the tracked window's half-width as an angle (rad), the widest of the cameras':
        # ``_window_neighbours`` and the occlusion hull's margin
        self._window_rad = max((0.5 * w / f_cam[n] for n, w in win.items() if f_cam.get(n)), default=0.0)
        self.timings: dict[str, float] = dict.fromkeys(STAGES, 0.0)
        self._tracks: dict[int, _Track] = {}
        self._last_t: float | None = None
        self._last_frame: int | None = None
        self._T_C_B_inv = {c.name: c.T_C_B.inverse() for c in rig}
        # the largest camera centre offset from the body origin (m): ``_occluded_by_members``
        self._cam_offset_m = max((float(np.linalg.norm(T.t)) for T in self._T_C_B_inv.values()), default=0.0)
        self._cam_index = {n: i for i, n in enumerate(rig.names)}
        self._features = _FeatureRays()
        self._slid_fids: set[int] | None = None  # feature ids _slid_features flagged this frame
        # track id -> the gate its member features failed this frame (_features_batch, _why_unranged)
        self._feature_why: dict[int, str] = {}
        self._gidx: dict[int, int] = {}
        self._members_ls = self._members_st = None
        self._stereo_pairs = None
        self._st_last: tuple | None = None  # shared features' last two-ray points (_stereo_jumps)
        self._speed_cache: dict[float, float] = {}
        self._FQ_cache: dict[tuple[float, bool], tuple[np.ndarray, np.ndarray]] = {}
        self._prev_members: tuple[np.ndarray, np.ndarray] | None = None  # (ids sorted, track ids)
        self._prev_t: float | None = None
        s = self.settings
        self._gate2 = self._chi2_gate(2)
        self._gate3 = self._chi2_gate(3)

    # ------------------------------------------------------------------------------- public API
    @property
    def track_ids(self) -> tuple[int, ...]:
        """Ids of the tracks with a live filter or history."""
        return tuple(self._tracks)

    def state(self, track_id: int) -> tuple[np.ndarray, np.ndarray, float] | None:
        """(x (6,) = [p_W, v_W], P (6, 6), t_s of the state) of a track's filter, or None."""
        tr = self._tracks.get(track_id)
        if tr is None or tr.kf is None:
            return None
        return tr.kf.x.copy(), tr.kf.P.copy(), tr.t_kf

    def step(self, observations: list[ObstacleObservation], frame: int, t_s: float) -> list[TrackReport]:
        """Fuse one frame's observations; returns one TrackReport per observed (or just ended) track.

        observations: the front end's ObstacleObservation list for this frame (their ``t_s`` must
        equal ``t_s``). frame: index (for messages). t_s: frame time, seconds, strictly increasing.
        Raises InputError for a non-finite, repeated or decreasing ``t_s`` (naming the frame), a time
        the ego-motion does not cover, an unknown camera or a repeated track id.

        ``timings`` covers the whole call: ``estimate`` (input checks, poses, bearings to W, bounds,
        feature and stereo triangulations) and ``fuse`` (filters and reports).
        """
        perf = time.perf_counter
        t0 = perf()
        t_s = self._check_time(frame, t_s)
        try:
            T_W_B = self.egomotion.pose_at(t_s)
        except InputError as e:
            raise InputError(f"{frame_at(frame, t_s)}: ego-motion: {e}") from e
        fc = _FrameContext(T_W_B, self.egomotion.velocity_at(t_s), t_s)
        reports: list[TrackReport] = []
        seen: set[int] = set()
        self._gidx: dict[int, int] = {}  # track id -> its index in this frame's work (members' groups)
        self._members_ls = self._members_st = None
        self._stereo_pairs = None
        todo: list[tuple[_Track, ObstacleObservation]] = []
        t_end = 0.0  # time spent reporting tracks ended in this loop (fuse)
        for obs in observations:  # all checked before any state changes: a bad frame leaves none changed
            self._check_obs(obs, frame, t_s, seen)
        for new, tr in self._continued(observations):
            te = perf()
            old = tr.id
            reports.append(self._end(tr, t_s, fc))  # the absorbed id reported lost once, as before
            t_end += perf() - te
            tr.id = new  # ... and its filter goes on under the id that took its members
            self._tracks[new] = tr
            if self._prev_members is not None:
                pid, ptr = self._prev_members
                self._prev_members = (pid, np.where(ptr == old, new, ptr))
        for obs in observations:
            tr = self._tracks.get(obs.track_id)
            if obs.status == "lost" or not obs.views:
                if tr is not None:
                    te = perf()
                    reports.append(self._end(tr, t_s, fc))
                    t_end += perf() - te
                continue
            if tr is None:
                tr = self._tracks[obs.track_id] = _Track(obs.track_id, obs.label)
            tr.label, tr.attributes = obs.label, dict(obs.attributes)
            todo.append((tr, obs))
        work, feats = self._sightings(todo, frame, t_s, T_W_B)
        self._member_resets(work, feats, t_s)
        self._gidx = {tr.id: i for i, (tr, _sg, _st) in enumerate(work)}
        self._bounds_batch(work)
        self._features_batch(work, t_s, feats)
        ev = [tr for tr, _sg, _st in work if tr.vel_acc is not None]
        if ev:  # "moving" re-decided every frame with the evidence's covariance grown to now
            for tr, m in zip(ev, self._evidence_now(ev, t_s)[1], strict=True):
                tr.vel_moving = m
        t1 = perf()
        t_est = t1 - t0 - t_end
        batch: list[tuple[_Track, _Sighting]] = []
        rest: list[tuple[_Track, _Sighting]] = []
        for tr, sg, _status in work:
            if (tr.feature_range is not None or tr.feature_point is not None) and (
                    tr.vel_moving or self._filter_moving(tr, t_s) or self._carried_moving(tr, t_s)):
                # its velocity evidence (or its filter's velocity, or the velocity it carried over a
                # restart) rejects a static obstacle: its features' static points are
                tr.feature_range = tr.feature_point = None  # not its range
            if tr.feature_range is not None and (not tr.moving or self.settings.feature_ranging_moving):
                batch.append((tr, sg))  # member features fit static points: they range the track
            else:
                rest.append((tr, sg))
        if rest:
            te = perf()
            wants = [tr.feature_stereo is None and len(sg.views) >= 2 and not self._ghost_prone(tr, sg)
                     for tr, sg in rest]
            need = [sg for (_tr, sg), w in zip(rest, wants, strict=True) if w]
            fixes = iter(self._stereo_batch(need) if need else ())
            t_est += perf() - te
            for (tr, sg), w in zip(rest, wants, strict=True):
                t_est += self._process(tr, sg, next(fixes) if w else None)
        if batch:
            self._set_from_features_batch(batch, fc)
        reports.extend(self._reports([(tr, status) for tr, _sg, status in work], fc))
        for tid in list(self._tracks):
            tr = self._tracks[tid]
            if tid not in seen and t_s - tr.last_seen_t > self.settings.lost_after_s:
                reports.append(self._end(tr, t_s, fc))
        if len(self._speed_cache) > 256:
            self._speed_cache.clear()
        if len(self._FQ_cache) > 64:
            self._FQ_cache.clear()
        self._last_t, self._last_frame = t_s, frame
        t2 = perf()
        self.timings = {"estimate": t_est, "fuse": t2 - t0 - t_est}
        return reports

    # ---------------------------------------------------------------------------- input checks
    def _check_time(self, frame: int, t_s: float) -> float:
        try:
            t = float(t_s)
        except (TypeError, ValueError):
            raise InputError(f"frame {frame}: expected a time t_s in seconds, got {t_s!r}") from None
        if not math.isfinite(t):
            raise InputError(f"frame {frame}: t_s must be finite, got {t_s!r}")
        if self._last_t is not None and t <= self._last_t:
            what = "repeats" if t == self._last_t else "goes back from"
            raise InputError(
                f"frame {frame}: t_s={t:.6f} s {what} the previous frame's t_s={self._last_t:.6f} s "
                f"(frame {self._last_frame}); expected strictly increasing times"
            )
        return t

    def _check_obs(self, obs: ObstacleObservation, frame: int, t_s: float, seen: set[int]) -> None:
        if obs.track_id in seen:
            raise InputError(f"frame {frame}: track id {obs.track_id} appears twice in one frame")
        seen.add(obs.track_id)
        if abs(obs.t_s - t_s) > 1e-6:
            raise InputError(
                f"frame {frame}: observation of track {obs.track_id} has t_s={obs.t_s:.6f} s, "
                f"expected the frame's t_s={t_s:.6f} s"
            )
        for v in obs.views:
            if v.camera not in self._T_C_B_inv:
                raise InputError(
                    f"frame {frame}: track {obs.track_id} seen by unknown camera {v.camera!r}; "
                    f"rig cameras: {', '.join(self.rig.names)}"
                )

    def _sightings(self, todo: list[tuple[_Track, ObstacleObservation]], frame: int, t_s: float,
                   T_W_B: Pose):
        """Every observed track's _Sighting of this frame, its bearings in W (one matrix product per
        camera for all tracks' representative and feature bearings: b_W = R_W_C b_C with
        R_W_C = R_W_B R_B_C, c_W = R_W_B t_B_C + t_W_B).

        Returns (work, feats): work = [(track, sighting, status)] in ``todo``'s order; feats =
        (ids (M,), b_W (M, 3), c_W (M, 3), track index (M,), camera index (M,)) of all member
        features (track by track, each track's views in the rig's order) and the first views'
        bearings b_W (G, 3), or None without any feature.
        """
        floor = self.settings.bearing_sigma_floor_rad
        cam_index = self._cam_index
        ncam = len(cam_index)
        R_W_C = np.empty((ncam, 3, 3))
        c_W = np.empty((ncam, 3))
        for name, T_B_C in self._T_C_B_inv.items():  # T_W_C = T_W_B T_B_C
            k = cam_index[name]
            R_W_C[k] = T_W_B.R @ T_B_C.R
            c_W[k] = T_W_B.R @ T_B_C.t + T_W_B.t
        c_rows = list(c_W)  # one (3,) array per camera, shared by its views
        c_tup = [tuple(c.tolist()) for c in c_rows]
        if not todo:
            return [], None
        vs_l, cam_l = [], []
        order = cam_index.__getitem__
        for _tr, obs in todo:
            vs = obs.views
            if len(vs) > 1:
                ks = [order(w.camera) for w in vs]
                ks_sorted = sorted(ks)
                if ks != ks_sorted:  # (not in the rig's order: sorted, stable)
                    vs = sorted(vs, key=lambda w: order(w.camera))
                    ks = ks_sorted
                cam_l.extend(ks)
            else:
                cam_l.append(order(vs[0].camera))
            vs_l.append(vs)
        n_v = [len(vs) for vs in vs_l]  # views per track
        one = len(cam_l) == len(vs_l)  # (one view per track: a mono rig)
        allv = [vs[0] for vs in vs_l] if one else [v for vs in vs_l for v in vs]
        fid_l = [v.feature_ids for v in allv]
        n_l = [len(f) for f in fid_l]
        B = np.array([v.b_C for v in allv])  # (V, 3) camera bearings
        vcam = np.array(cam_l, dtype=np.int64)
        fcnt = np.array(n_l, dtype=np.int64)
        M = int(fcnt.sum())
        B = _rotate_rows(B, vcam, R_W_C)
        B /= np.sqrt(B[:, 0] * B[:, 0] + B[:, 1] * B[:, 1] + B[:, 2] * B[:, 2])[:, None]
        b_rows = list(B)
        nv = np.array(n_v, dtype=np.int64)
        first_view = nv.cumsum() - nv  # each track's first view
        feats = None
        FB = None
        if M:
            ids = np.concatenate(fid_l)
            FB = np.concatenate([v.feature_b_C for v in allv])
            fcam = vcam.repeat(fcnt)
            FB = _rotate_rows(FB, fcam, R_W_C)
            trk = np.arange(len(vs_l), dtype=np.int64)  # each view's track
            if not one:
                trk = trk.repeat(nv)
            feats = (ids, FB, c_W.take(fcam, 0), trk.repeat(fcnt), fcam, B.take(first_view, 0))
        offs = (fcnt.cumsum() - fcnt).tolist()
        o_W = T_W_B.t
        mk = _View
        sig_l = [float(v.sigma_rad if v.sigma_rad > floor else floor) for v in allv]
        vobj = [mk(v.camera, c_rows[k], b, sg, f, FB[o:o + n]) if n else mk(v.camera, c_rows[k], b, sg)
                for v, k, b, sg, f, n, o in zip(allv, cam_l, b_rows, sig_l, fid_l, n_l, offs, strict=True)]
        work = []
        j = 0
        for (tr, obs), n in zip(todo, n_v, strict=True):
            if n == 1:
                sg = _Sighting(t_s, frame, o_W, (vobj[j],), c_tup[cam_l[j]], (offs[j],))
            else:
                sg = _Sighting(t_s, frame, o_W, tuple(vobj[j:j + n]), c_tup[cam_l[j]], tuple(offs[j:j + n]))
            j += n
            tr.feature_range = None
            tr.feature_stereo = None
            tr.feature_point = None
            tr.feature_point_fid = None
            tr.feature_stereo_point = None
            tr.feature_velocity = None
            work.append((tr, sg, obs.status))
        return work, feats

    # ------------------------------------------------------------------------------- per track
    def _member_resets(self, work: list[tuple[_Track, _Sighting, str]], feats, t_s: float) -> None:
        """Restart the tracks whose member set was replaced since the previous frame (see
        ``member_reset_frac``): new share = (member rays whose feature id was not this track's member
        in the previous frame) / (member rays now), over all views, for tracks with >= 2 member
        rays now and then (the share of a single ray says nothing); one sorted look-up for all
        tracks. A replaced track is restarted (``_restart``)."""
        s = self.settings
        prev, t_prev = self._prev_members, self._prev_t
        self._prev_t = t_s
        if feats is None:
            self._prev_members = None
            return
        ids, g = feats[0], feats[3]
        G = len(work)
        tids = np.fromiter((tr.id for tr, _sg, _st in work), dtype=np.int64, count=G)
        owner = tids[g]
        n = np.bincount(g, minlength=G)
        order = ids.argsort(kind="stable")
        self._prev_members = (ids[order], owner[order])
        if s.member_reset_frac >= 1.0 or prev is None or not len(prev[0]):
            off = (n.cumsum() - n).tolist()
            for (tr, _sg, _st), nk, o in zip(work, n.tolist(), off, strict=True):
                tr.n_members, tr.t_members = nk, t_s
                tr.member_ids = ids[o:o + nk]
            return
        pid, ptr = prev
        j = np.minimum(pid.searchsorted(ids), len(pid) - 1)
        new = ~((pid[j] == ids) & (ptr[j] == owner))  # not this track's member last frame
        n_new = np.bincount(g, weights=new, minlength=G)
        m = 2  # fewest member rays now and then (one ray's share is 0 or 1)
        off = (n.cumsum() - n).tolist()  # (feats are grouped track by track, in work's order)
        frac = s.member_reset_frac
        for (tr, _sg, _st), nk, o, nn in zip(work, n.tolist(), off, n_new.tolist(), strict=True):
            if nk >= m and tr.n_members >= m and (tr.kf is not None or tr.history):
                if tr.t_members != t_prev:  # not seen in the previous frame: against its last member set
                    nn = float(nk - np.count_nonzero(_isin(ids[o:o + nk], tr.member_ids)))
                if nn > frac * nk:
                    ev = self._motion_evidence(tr, t_s) if s.restart_keeps_motion else None
                    self._restart(tr, "member features replaced: filter restarted")
                    tr.motion_carry = ev
            tr.n_members, tr.t_members = nk, t_s
            tr.member_ids = ids[o:o + nk]

    def _motion_evidence(self, tr: _Track, t_s: float) -> tuple | None:
        """The obstacle velocities a track has measured that reject zero at t_s, as velocity
        evidence ((v (3,) m/s, P (3, 3) m^2/s^2, t_e s), ...; ``_velocity_evidence``) to keep over a
        member-replacement restart: the tests that kept its features' static points from ranging
        it before the restart, each kept: its evidence ``vel_acc`` (``vel_moving``), its moving
        filter's velocity (x[3:], P_vv at t_kf; ``_filter_moving``'s, an assumed velocity too:
        the prior's zero rejects nothing, so one that does was measured by the fixes since), and
        those it carried over an earlier restart (``motion_carry``); None without any."""
        cands = [e for e in (tr.vel_acc, *(tr.motion_carry or ())) if e is not None]
        if tr.kf is not None and tr.moving:
            cands.append((tr.kf.x[3:].copy(), tr.kf.P[3:, 3:].copy(), tr.t_kf))
        keep = tuple(e for e in cands if self._rejects_zero(e, t_s))
        return keep or None

    def _carried_moving(self, tr: _Track, t_s: float) -> bool:
        """Whether a velocity a track carried over a member-replacement restart (``motion_carry``
        = ((v, P, t_e), ...)) still rejects zero at t_s: v^T (P + q (t_s - t_e) I)^-1 v > chi2_3(
        gate_probability), q = max_accel_mps2^2 accel_time_s (``_evidence_now``'s test). Evidence
        that no longer rejects zero is dropped: it decides nothing after it has aged."""
        if tr.motion_carry is None:
            return False
        keep = tuple(e for e in tr.motion_carry if self._rejects_zero(e, t_s))
        tr.motion_carry = keep or None
        return bool(keep)

    def _rejects_zero(self, e: tuple, t_s: float) -> bool:
        """``_evidence_now``'s test for one velocity evidence e = (v (3,) m/s, P (3, 3), t_e s):
        v^T P(t_s)^-1 v > chi2_3(gate_probability), P(t_s) = ``_grown(e, t_s)``."""
        v, P = e[0], self._grown(e, t_s)
        try:
            chi = float(v @ np.linalg.solve(P, v))
        except np.linalg.LinAlgError:  # singular (a zero prior and no process noise):
            chi = float(v @ np.linalg.pinv(P) @ v)  # the chi over what is measured
        return chi > self._gate3

    @staticmethod
    def _restart(tr: _Track, reason: str) -> None:
        """The one restart path (members replaced, or ``reinit_after_gated`` gated updates in a
        row): drop a track's filter and everything tied to its old points (sightings, bounds,
        velocity reference and evidence, moving hypothesis); it keeps its id, label, gate counters
        and sources. A member replacement (before this frame's estimates) starts it again from this
        frame's measurements; a gated run (after this frame's update) keeps only this frame's
        sighting and initialises again from the next frame on."""
        tr.kf = None
        tr.moving = False
        tr.vel_assumed = False
        tr.vel_ref = None
        tr.vel_acc = None
        tr.vel_moving = False
        tr.motion_carry = None
        tr.feature_stereo_fid = None
        tr.feature_stereo_anchor = False
        tr.point_fid = None
        tr.point_is_feature = False
        tr.pair_tested = None
        tr.history.clear()
        tr.bounds = None
        tr.gated_run = 0
        tr.t_ranged = -math.inf
        tr.reason = reason

    def _speed(self, t_s: float) -> float:
        v = self._speed_cache.get(t_s)
        if v is None:
            v = self._speed_cache[t_s] = float(np.linalg.norm(self.egomotion.velocity_at(t_s)))
        return v

    def _max_speed(self, t_a: float, t_b: float) -> float:
        s = self.settings.max_speed_mps
        if s is not None:
            return float(s)
        return max(self._speed(t_a), self._speed(t_b))

    def _ghost_prone(self, tr: _Track, sg: _Sighting) -> bool:
        """Whether the two cameras' representative bearings of this sighting are likely different
        physical points: both views list member features and either share none of them, or each
        lists enough for a feature stereo fix (>= stereo_feature_min_count) and they still gave none
        (too few shared ids). Feature ids are physical-point ids, so two views sharing no id give no
        evidence that their representative rays meet at one point; their triangulation is then a
        ghost (tracked stereo_hover, sphere at 1.4 m: +30 % every frame; fps100_stereo_flying's box:
        0.36 m against 1.9 m from a view of one ground feature beside a view of four box features,
        rays 21.8 deg apart). So it is not used: no stereo fix, and only the first view's bearing is
        fused (both bearings fused into one state would triangulate them all the same; the first
        view's is the one the track's mono pairs and bounds use) (tracked pipeline scenes with the
        fix used instead: stereo <= 3 m median 1.30 -> 1.32 %, no gain elsewhere). Views without
        member features (box tracks, bearings mode) carry no ids to compare: their representative
        bearings are triangulated."""
        if tr.feature_stereo is not None or len(sg.views) < 2:
            return False
        fa, fb = sg.views[0].feature_ids, sg.views[1].feature_ids
        if not len(fa) or not len(fb):
            return False
        m = max(1, self.settings.stereo_feature_min_count)
        return (len(fa) >= m and len(fb) >= m) or not _isin(fa, fb).any()

    def _mono_views(self, tr: _Track, sg: _Sighting) -> tuple[_View, ...]:
        """The views of sighting sg whose representative bearings a track's state takes: all, or the
        first alone when the two are likely different points (``_ghost_prone``)."""
        return sg.views[:1] if self._ghost_prone(tr, sg) else sg.views

    def _supported_update(self, tr: _Track, sg: _Sighting, scale: float = 1.0) -> None:
        """Update a state that stands for one member feature's point (``point_fid``: the median
        feature's own point when ``feature_point`` set it, or the member whose ray passed nearest a
        mono triangulation of the representative rays) in a frame whose features do not range it.

        The representative bearing is a centroid of members that may lie several degrees from
        that point, on another surface (a mixed or sparse track), so it is not a measurement of the
        point: fusing it moved carried states onto the bearing of a nearer obstacle while keeping
        the background's range (tracked pipeline scenes: 16 tuned / 33 held-out reports whose
        bearing hit an obstacle no member was on made 29 % / 45 % of the range NEES sum). Instead:
          * a feature-point state is updated with that feature's own current ray(s), bearing sigma
            feature_point_sigma_k * feature_sigma_rad (the tracked features' measured error);
          * a triangulated state whose support member is still listed takes the representative
            bearing as before (it stands for the representative ray's point);
          * when the feature is no longer a member, nothing the track observes supports the state
            (a static point no member sees, e.g. one now hidden behind a nearer obstacle): the
            filter is dropped and the range is not reported until the members range it again.
        """
        fid = tr.point_fid
        seen = [(v, int((v.feature_ids == fid).nonzero()[0][0]))
                for v in sg.views if (v.feature_ids == fid).any()]
        if seen and tr.point_is_feature and self._slid_fids is not None and fid in self._slid_fids:
            tr.kf = None  # the feature slid off the point the state stands for (_slid_features)
            tr.point_fid = None
            tr.point_is_feature = False
            tr.reason = "the member feature its range was measured on slid off its point"
            return
        if not seen:
            tr.kf = None
            tr.point_fid = None
            tr.point_is_feature = False
            tr.reason = "the member feature its range was measured on is no longer tracked"
            return
        if tr.point_is_feature:
            sig_f = self.settings.feature_point_sigma_k * self.settings.feature_sigma_rad
            for v, j in seen:
                self._bearing_update(tr, _View(v.camera, v.c_W, v.feature_b_W[j], sig_f), scale)
        else:
            for v in self._mono_views(tr, sg):
                self._bearing_update(tr, v, scale)
        tr.sources.add("mono")

    def _repeat_scale(self, t_last: float, t_s: float) -> float:
        """The factor c = max(1, tau / dt) >= 1 on the noise covariance R of a track's bearing and
        point updates at t_s, dt = t_s - t_last the time since its previous update (one a frame:
        its last sighting, or in ``_init_mono``'s replay the sighting before), tau =
        measurement_correlation_s: its measurements come from the same tracked features, whose
        errors drift together, so updates closer than tau carry dt / tau of one's information and
        the evidence grows per second, not per frame."""
        tau = self.settings.measurement_correlation_s
        dt = t_s - t_last
        return tau / dt if 0.0 < dt < tau else 1.0

    def _process(self, tr: _Track, sg: _Sighting, stereo_fix=None) -> float:
        """Update one track that its member features do not range (``_set_from_features_batch``
        does those): stereo / mono initialisation or prediction and bearing / point updates, then
        the bounds. stereo_fix: ``_stereo_batch``'s result for this sighting (tracks seen by two
        cameras without a feature stereo fix). Returns the seconds spent on estimates."""
        s = self.settings
        t0 = time.perf_counter()
        stereo = None
        if tr.feature_stereo is not None:  # the common features' own stereo range (no ghosts)
            stereo = self._stereo_from_features(tr, sg)
        elif len(sg.views) >= 2:
            stereo = stereo_fix
        if stereo is not None and tr.feature_stereo is None and tr.feature_range is not None:
            # two independent ranges: a stereo fix from the representative bearings that disagrees
            # with the member features' range by > 3 sigma is a mismatch of the two cameras'
            # representative points (different parts of the object), not a measurement
            z, sz, _ = tr.feature_range
            r_st = float(np.linalg.norm(stereo[0] - sg.o_W))
            u = (stereo[0] - sg.o_W) / max(r_st, 1e-9)
            s_st = math.sqrt(max(float(u @ stereo[1] @ u), 0.0))
            if abs(r_st - z) > 3.0 * math.hypot(sz, s_st):
                stereo = None
                tr.gated += 1
        init_pair = None
        if (stereo is None and not tr.moving and tr.feature_range is None
                and len(sg.views[0].feature_ids) >= s.feature_min_count):
            # its member features do not range it (yet): the representative ray, a centroid that
            # slides over the object and its background, is no better (no made-up range; tracked
            # pipeline scenes ranging it from that ray's parallax instead: mono p90 3.59 -> 3.90 %,
            # range NEES mean 3.5 -> 4.9 for a mono coverage of 93.4 instead of 92.2 %)
            tr.kf = None
            init_pair = self._feature_why.get(tr.id,
                                              "member features do not range it (parallax, spread or fit)")
        elif tr.kf is None and stereo is None and tr.feature_range is None:
            init_pair = self._mono_init_pair(tr, sg)
        t1 = time.perf_counter()
        tr.bounded_now = False
        if tr.kf is None:
            if stereo is not None:
                self._init_stereo(tr, sg, stereo)
            elif isinstance(init_pair, tuple):
                self._init_mono(tr, sg, *init_pair)
            else:
                tr.reason = init_pair if isinstance(init_pair, str) else "no earlier sighting yet"
        else:
            c = self._repeat_scale(tr.last_seen_t, sg.t_s)  # (>= 1: updates closer than tau)
            self._predict(tr, sg.t_s)
            if stereo is not None:
                if not tr.moving:  # first stereo fix: velocity becomes observable, drop the static prior
                    self._to_moving(tr, sg.t_s)
                    tr.vel_assumed = tr.feature_stereo is not None and s.feature_velocity_lag_s > 0
                if tr.feature_stereo is not None and tr.feature_stereo_anchor:
                    self._anchor_position(tr, *stereo)  # (the state is on another point)
                elif tr.feature_stereo is not None:
                    # (a feature stereo fix lies on the first camera's representative ray; the
                    # second camera's representative bearing points at another part of the object)
                    self._point_update(tr, *stereo, c)
                else:  # the two cameras' bearings: Gaussian noise, no double counting
                    for v in sg.views:
                        self._bearing_update(tr, v, c)
                tr.sources.add("stereo")
                tr.t_ranged = sg.t_s
                tr.point_fid = None  # (the state is the stereo fixes' point now)
                tr.point_is_feature = False
                if tr.feature_velocity is not None:  # its features' own displacements
                    self._velocity_update(tr, *tr.feature_velocity)
                elif tr.vel_assumed and tr.vel_acc is not None:  # (no measurement this frame)
                    self._adopt_velocity_evidence(tr)
            elif tr.point_fid is not None:  # the state is one member feature's point (support)
                self._supported_update(tr, sg, c)
            else:  # (only the first view's bearing when the two are different points: ghost)
                for v in self._mono_views(tr, sg):
                    self._bearing_update(tr, v, c)
                tr.sources.add("mono")
            if tr.gated_run >= s.reinit_after_gated:  # diverged or re-associated: start again
                self._restart(tr, f"filter restarted after {s.reinit_after_gated} gated measurements")
        if tr.kf is not None and not tr.moving:  # stereo measures range itself; the bounds
            self._apply_bounds(tr, sg)              # rest on an assumed max speed
        tr.history.append(sg)
        tr.last_seen_t = sg.t_s
        tr.last_views = sg.views
        tr.cameras = (sg.views[0].camera,) if len(sg.views) == 1 else tuple([v.camera for v in sg.views])
        return t1 - t0

    def _continued(self, observations: list[ObstacleObservation]) -> list[tuple[int, _Track]]:
        """Filters that go on under another id: a track reported lost this frame as merged into
        another id (``attributes["merged_into"]``, the front end's ``_merge_gids``) whose filter has a
        state (``kf``) ranged more recently than that id's track (``t_ranged``; or that track has no
        state) is continued under that id: the merge keeps the better-informed filter, not the one
        the kept id happened to key (the front end keeps the id seen longer, ``_survivor``, or the
        box's). The lost id is still reported lost once. Returns (that id, the lost track) pairs, at
        most one per id."""
        here = {o.track_id for o in observations if o.status != "lost" and o.views}
        out: list[tuple[int, _Track]] = []
        used: set[int] = set()
        for o in observations:
            into = o.attributes.get("merged_into") if o.status == "lost" else None
            tr = self._tracks.get(o.track_id)
            if into is None or into not in here or into in used or tr is None or tr.kf is None:
                continue
            r = self._tracks.get(into)
            if r is not None and r.kf is not None and r.t_ranged >= tr.t_ranged:
                continue
            used.add(into)
            out.append((into, tr))
        return out

    def _end(self, tr: _Track, t_s: float, fc: _FrameContext) -> TrackReport:
        """Report a track once as lost (predicted to t_s) and drop its filter."""
        if tr.kf is not None:
            self._predict(tr, t_s)
        tr.bounded_now = False
        rep = self._reports([(tr, "lost")], fc)[0]
        del self._tracks[tr.id]
        return rep

    # ------------------------------------------------------------------------------- estimates
    def _stereo_batch(self, sightings: list[_Sighting]) -> list:
        """Triangulate the first two views of each sighting (``geometry.triangulate_batch``, the
        midpoint method): per sighting (p_W (3,), R (3, 3)) or None when unusable (degenerate,
        range sigma above stereo_max_rel_sigma of the range, or rays that miss each other by more
        than 4 sqrt(2) sigma times their depth). Range sigma is linear in the bearing sigma
        (first order), so the batch runs at sigma 1 and each row is scaled by its own
        sigma = sqrt((sigma_a^2 + sigma_b^2) / 2)."""
        va = [sg.views[0] for sg in sightings]
        vb = [sg.views[1] for sg in sightings]
        c_a = np.array([v.c_W for v in va])
        c_b = np.array([v.c_W for v in vb])
        sa = np.array([v.sigma_rad for v in va])
        sb = np.array([v.sigma_rad for v in vb])
        sigma = np.sqrt(0.5 * (sa * sa + sb * sb))
        tri = geometry.triangulate_batch(c_a, np.array([v.b_W for v in va]), c_b,
                                         np.array([v.b_W for v in vb]), origin=c_b, bearing_sigma_rad=1.0)
        sig_r = tri.range_sigma_m * sigma
        ok = (tri.valid & (sig_r <= self.settings.stereo_max_rel_sigma * tri.range_m)
              & (tri.miss_m <= 4.0 * math.sqrt(2.0) * sigma * np.maximum(tri.depth_a_m, tri.depth_b_m)))
        out: list = [None] * len(sightings)
        k = ok.nonzero()[0]
        if len(k):
            c_mid = 0.5 * (c_a[k] + c_b[k])
            R = _ray_covariances(tri.p[k] - c_mid, sig_r[k], sigma[k])
            for j, kk in enumerate(k.tolist()):
                out[kk] = (tri.p[kk], R[j])
        return out

    def _mono_init_pair(self, tr: _Track, sg: _Sighting):
        """(past sighting, Triangulation) with enough parallax, or a reason string."""
        if not tr.history:
            return "no earlier sighting yet"
        vb = sg.views[0]
        cb = sg.c0
        hist = tr.history
        # the longest baseline: largest |c - c_b|^2 (first of ties; Python floats, no arrays)
        x, y, z = cb
        best, best_b2 = None, -math.inf
        for h in hist:
            c = h.c0
            d2 = (c[0] - x) ** 2 + (c[1] - y) ** 2 + (c[2] - z) ** 2
            if d2 > best_b2:
                best, best_b2 = h, d2
        if best is None:  # (every baseline NaN: non-finite camera centres)
            return "no earlier sighting with a finite baseline"
        va = best.views[0]
        cos_par = float(va.b_W @ vb.b_W)  # cheap pre-check of the parallax before triangulating
        if cos_par > math.cos(self.settings.min_parallax_rad) and best_b2 > 1e-18:
            par = math.acos(min(cos_par, 1.0))
            return (
                f"parallax {math.degrees(par):.2f} deg below the "
                f"{math.degrees(self.settings.min_parallax_rad):.2f} deg needed"
            )
        sigma = math.sqrt(0.5 * (va.sigma_rad**2 + vb.sigma_rad**2))
        # cheap pre-check of the relative range sigma, ~ sqrt(2) sigma / sin(parallax) (the first-
        # order sigma below differs from it by a geometry factor near 1): skip hopeless pairs
        sin_par = math.sqrt(max(1.0 - min(cos_par * cos_par, 1.0), 0.0))
        rel_est = math.sqrt(2.0) * sigma / max(sin_par, 1e-12)
        if rel_est > 2.0 * self.settings.mono_init_max_rel_sigma and best_b2 > 1e-18:
            return (
                f"mono triangulation too uncertain (sigma ~{100 * rel_est:.0f} % > "
                f"{100 * self.settings.mono_init_max_rel_sigma:.0f} %)"
            )
        tri = geometry.triangulate(va.c_W, va.b_W, vb.c_W, vb.b_W, origin=vb.c_W, bearing_sigma_rad=sigma)
        if not isinstance(tri, geometry.Triangulation):
            return f"mono triangulation unobservable: {tri.reason}"
        if tri.parallax_rad < self.settings.min_parallax_rad:
            return (
                f"parallax {math.degrees(tri.parallax_rad):.2f} deg below the "
                f"{math.degrees(self.settings.min_parallax_rad):.2f} deg needed"
            )
        if tri.range_sigma_m > self.settings.mono_init_max_rel_sigma * tri.range_m:
            return (
                f"mono triangulation too uncertain (sigma {100 * tri.range_sigma_m / tri.range_m:.0f} % > "
                f"{100 * self.settings.mono_init_max_rel_sigma:.0f} %)"
            )
        return best, tri

    def _bounds_batch(self, work: list[tuple[_Track, _Sighting, str]]) -> None:
        """Moving-obstacle bounds of every track of this frame at once (see the module docstring): the
        current sighting against the oldest one in the baseline window, whose older sightings are
        dropped here. The 5-6 ray pairs of each track (``_noisy_bound_rays_batch``) are evaluated
        in one ``geometry.moving_obstacle_bounds_batch`` call and united per track."""
        s = self.settings
        max_age = s.baseline_max_age_s + 1e-9
        nsig = s.bounds_noise_sigmas
        idx: list[int] = []
        ca_l, ba_l, cb_l, bb_l, D_l, dl_l = [], [], [], [], [], []
        D_cache: dict[float, float] = {}
        hypot = math.hypot
        for i, (tr, sg, _st) in enumerate(work):
            hist = tr.history
            t_now = sg.t_s
            tr.bounds = None
            if hist:
                h = hist[0]
                while t_now - h.t_s > max_age:
                    hist.popleft()
                    if not hist:
                        break
                    h = hist[0]
            if not hist:
                tr.bounds_reason = "no earlier sighting yet"
                continue
            tr.bounds_reason = None
            va, vb = h.views[0], sg.views[0]
            idx.append(i)
            ca_l.append(va.c_W)
            ba_l.append(va.b_W)
            cb_l.append(vb.c_W)
            bb_l.append(vb.b_W)
            t_h = h.t_s
            D = D_cache.get(t_h)
            if D is None:  # eq. 3.11-3.13: FC = GC = v dt (one per earlier frame)
                D = D_cache[t_h] = self._max_speed(t_h, t_now) * (t_now - t_h)
            D_l.append(D)
            dl_l.append(nsig * hypot(va.sigma_rad, vb.sigma_rad))
        if not idx:
            return
        rows, c_a, b_a, c_b, b_b = _noisy_bound_rays_batch(
            np.array(ca_l), np.array(ba_l), np.array(cb_l), np.array(bb_l), np.array(dl_l))
        D = np.array(D_l)[rows]
        o = np.broadcast_to(work[0][1].o_W, c_a.shape)
        r_min, r_max, _d_min, _d_max, ok = geometry.moving_obstacle_bounds_batch(c_a, b_a, c_b, b_b, D, o)
        G = len(idx)
        lo = np.full(G, np.inf)
        hi = np.full(G, -np.inf)
        own = rows[ok]
        np.minimum.at(lo, own, r_min[ok])
        np.maximum.at(hi, own, r_max[ok])
        any_ok = np.zeros(G, dtype=bool)
        any_ok[own] = True
        r_floor = s.bounds_min_range_m
        inf = math.inf
        for i, good, lo_i, hi_i in zip(idx, any_ok.tolist(), lo.tolist(), hi.tolist(), strict=True):
            tr = work[i][0]
            # an upper bound at the camera itself (below bounds_min_range_m): the rays meet only
            # where they start, i.e. no point within the allowed motion (a hovering drone, max
            # speed = its own speed ~0, and an obstacle that moved): inconsistent, not "at 0 m"
            if good and not hi_i < r_floor:
                tr.bounds = _Bounds(lo_i, None if hi_i == inf else hi_i)  # (hi >= 0 here)
            else:
                tr.bounds_reason = "bounds unobservable: inconsistent with max speed"

    def _features_batch(self, work: list[tuple[_Track, _Sighting, str]], t_s: float, feats) -> None:
        """Member-feature ranges of all of this frame's tracks at once (static points and stereo).

        Every view's feature rays are added to the run's feature store (one ray per feature and
        camera; ids are physical points, so a feature seen by two cameras gets both rays). Then, for
        static-hypothesis tracks (``feature_ranging``), each present feature's least-squares point
        p_f (see _FeatureRays) counts when the angle between its first and current bearing
        (parallax) is >= 10 feature_sigma_rad on a mono rig (0.57 deg at 1e-3 rad; min_parallax_rad on
        a stereo rig), p_f lies in front of the camera, and its relative range
        sigma is at most mono_init_max_rel_sigma. That sigma is first order in the normal equations:
        each ray i misses p_f by ~ sigma_f d_i (d_i its own depth), so Cov(p_f) ~ sigma_f^2 D2 A_f^-1 and
            sigma_r,f = sigma_f sqrt(D2) sqrt(u^T A_f^-1 u),   u = (p_f - o) / |p_f - o|
        (D2 = mean_i d_i^2, ``_depth2``: flown at, the older rays are the farther ones)
        (two rays at parallax theta: sqrt(2) sigma_f d / (2 sin(theta / 2)) ~ sqrt(2) sigma_f d / theta).
        With >= feature_min_count of them and the features fitting static points (median chi):
            z = median_f |p_f - o_W|  (over the half angularly nearest the representative ray),
            sigma_z = (1 + k / n) sqrt((1.4826 MAD_inner)^2 + (w 1.4826 MAD_all)^2
                                       + median_f sigma_r,f^2 / n)
        (MAD: median absolute deviation; w = feature_mad_all_weight, k = feature_small_n_inflate).
        The inner half's spread is the obstacle's depth extent
        and stray members near the ray, which do not average out; the spread of all kept features
        stands for the offset between the surface point on the representative ray and the
        features (they sit on other parts of the object). On the rendered and tracked
        mono_straight scene the 1-sigma share went from 52 % (max(MAD_inner, sigma / sqrt(n)))
        to 71 % with this sum. Tracks seen by two cameras also get
        ``feature_stereo``: the features with one id in both views this frame, triangulated from
        these two rays only (valid for moving obstacles too), reduced the same way.
        All groups are computed in one vectorised pass (group medians by sorting).

        feats: (ids (M,), b_W (M, 3), c_W (M, 3), track index (M,), camera index (M,)) of this frame's
        member features and the first views' bearings (G, 3) (``_sightings``), or None.
        """
        s = self.settings
        fs = self._features
        self._slid_fids = None
        self._feature_why = {}
        fs.prune(t_s, s.lost_after_s)
        if feats is None:
            return
        ids, b_now, c_now, g, cam = feats[:5]
        rows = fs.rows(ids, b_now)
        ncam = len(self._cam_index)
        _, first = _unique_first(rows * ncam + cam)  # one ray per feature and camera
        fs.add(rows[first], b_now.take(first, 0), c_now.take(first, 0), t_s, s.feature_memory_s,
               unique=ncam == 1, short_memory_s=s.feature_slide_memory_s if ncam > 1 else 0.0,
               correlation_s=s.measurement_correlation_s)
        # the features on their track's outline in a view (``_outline_flags``): not chosen to range
        # the track while two interior ones can be
        # on a stereo rig only: the stereo fix's feature, and the static-point (multi-frame) fix's
        # feature too: the cameras sit off the body origin, so the body's ray toward a silhouette
        # corner that one camera tracks passes beside the obstacle (heldout_stereo_flying track
        # 92: a point at 1.04 m on obstacle 1's edge seen from cam0; the body's ray toward it hits
        # obstacle 3 at 3.85 m). (On a mono rig the rule for the static-point fix was a measured
        # trade, removed: see FusionSettings.feature_avoid_outline.)
        avoid_ls = avoid_st = s.feature_point and s.feature_avoid_outline and ncam > 1
        edge = np.zeros(len(ids), dtype=bool)
        if avoid_st:
            edge = _outline_flags(b_now, g * ncam + cam)
        if ncam > 1:
            self._feature_stereo(work, ids, b_now, c_now, feats[5], edge)
        if not s.feature_ranging:
            return
        G = len(work)
        eligible = np.array([s.feature_ranging_moving or not tr.moving for tr, _sg, _st in work])
        # one entry per (track, feature): the first camera's ray of it
        key_n = fs.size + 1
        # (track, feature) on an outline in a view
        edge_keys = np.unique(g[edge] * key_n + rows[edge]) if avoid_ls else None
        _, first = _unique_first(g * key_n + rows)
        first = first[eligible[g[first]]]
        if len(first) == 0:
            return
        g, rows, b_now, c_now = g[first], rows[first], b_now.take(first, 0), c_now.take(first, 0)
        n_min = s.feature_min_count
        cnt = np.bincount(g, minlength=G)
        b0 = fs.b0.take(rows, 0)
        cosp = _dot_rows(b0, b_now).clip(-1.0, 1.0)
        # (tracks with fewer than feature_min_count features get no feature range, but their
        # features' points still tell the spread of depths around the track: _member_spread)
        # parallax floor: theta >= 10 sigma_f, the bearing noise at most a tenth of the parallax,
        # so the first-order sigma_r,f below holds (the 1/theta bias ~ (sigma_f / theta)^2 <= 1 %);
        # the relative-sigma gate (mono_init_max_rel_sigma) decides whether the point ranges. (It was
        # min_parallax_rad, 1 deg: of the 40 validation obstacle-frames that _process's "member
        # features do not range it" left unranged with a track on the obstacle, 37 had < 3 members
        # over 1 deg, young tracks whose features had 0.6-1 deg over 3-6 rays at 5-10 % relative
        # sigma, e.g. val2_moving_crossing box #4 at t 1.0-1.83 s.)
        # On a stereo rig the 1 deg stays: a young track's range comes from its stereo fixes, which
        # a marginal static-point range would gate (tuned stereo_hover: stereo obstacle-frame
        # coverage 70.3 -> 66.5 % with the floor there too).
        par_min = 10.0 * s.feature_sigma_rad if ncam == 1 else s.min_parallax_rad
        good = cosp <= math.cos(max(par_min, 1e-6))
        cnt = self._why_unranged(work, cnt, g[good],
                                 f"fewer than {n_min} have {math.degrees(par_min):.2f} deg of parallax")
        if not good.any():
            return
        g, rows, b_now, c_now = g[good], rows[good], b_now.compress(good, 0), c_now.compress(good, 0)
        Sr = fs.S.take(rows, 0)  # the features' running sums (_FeatureRays._set_sums: A, y, bc, cc, bcc, n)
        adj, det = _adjugate_det3(Sr[:, 0:9].reshape(len(Sr), 3, 3))
        ok = det > 1e-12
        g, rows = g[ok], rows[ok]
        b_now, c_now, Sr = b_now.compress(ok, 0), c_now.compress(ok, 0), Sr.compress(ok, 0)
        if not len(g):
            return
        Ainv = adj.compress(ok, 0) / det[ok][:, None, None]  # A^-1 = adj(A) / det(A)
        p = _einsum("kij,kj->ki", Ainv, Sr[:, 9:12])  # A_f p_f = y_f
        o = work[0][1].o_W
        r_vec = p - o
        r = np.sqrt(_dot_rows(r_vec, r_vec))  # (np.linalg.norm's values)
        d_vec = p - c_now
        depth = _dot_rows(d_vec, b_now)
        # the current ray's own miss of p_f (rad^2): |(I - b b^T)(p_f - c)|^2 / d^2
        miss2 = np.maximum(_dot_rows(d_vec, d_vec) - depth * depth, 0.0) / np.maximum(depth * depth, 1e-12)
        u = r_vec / np.maximum(r, 1e-9)[:, None]
        # each ray i misses p_f by ~ sigma_f d_i (d_i its own depth, not the current one: flying at
        # an obstacle, the rays of the last 0.5 s were taken from up to twice as far; 15 m/s at
        # 6 m, mean d_i^2 ~ 5 d_now^2), so Cov(p_f) ~ sigma_f^2 mean_i(d_i^2) A_f^-1 (the d_i^2
        # weighted alike; ``_depth2``)
        pAp = _pAp(Sr, p)
        d2 = _depth2(Sr, p, pAp)
        sig_r = s.feature_sigma_rad * np.sqrt(d2) * np.sqrt(
            np.maximum(_einsum("ki,kij,kj->k", u, Ainv, u), 0.0))
        # in front of the camera by more than feature_min_depth_m: the rays of a feature seen from
        # one place only (hovering) all meet at the camera centre, a point of no range
        keep = (depth > s.feature_min_depth_m) & (sig_r <= s.mono_init_max_rel_sigma * r)
        cnt = self._why_unranged(work, cnt, g[keep], f"fewer than {n_min} meet in front of the camera with "
                                 f"a relative range sigma <= {100 * s.mono_init_max_rel_sigma:g} %")
        # ... but on a mono rig a feature whose bearing turned by the parallax floor while its rays
        # meet behind the camera (or at it) is no static point in front of it: noise of sigma_f
        # cannot carry a static point's ray intersection behind the camera across 10 sigma_f of
        # parallax. Its rays diverge: a moving point approaching faster than its parallax says
        # (tracked: the long-lived corners of val_heldout_moving's box 3 and val2_heldout_moving's
        # sphere 2, 10-15 rays each, least-squares points 0.2-1.6 m "away" behind the camera), or
        # a corner that jumped. It ranges nothing, but it is evidence against the static
        # hypothesis below.
        behind = None
        if s.feature_static_behind and ncam == 1:
            bh = depth <= s.feature_min_depth_m
            if bh.any():
                behind = (g[bh], fs.n[rows[bh]])
        if not keep.any():
            return
        g, rows, b_now, p, r, depth, sig_r, d2, miss2, Sr, pAp = (
            g[keep], rows[keep], b_now.compress(keep, 0), p.compress(keep, 0), r[keep], depth[keep],
            sig_r[keep], d2[keep], miss2[keep], Sr.compress(keep, 0), pAp[keep])
        # static-point test: each ray misses its feature's point by ~ sigma_f d_i per axis, so
        #   chi = mean_i miss_i^2 / (2 sigma_f^2 mean_i d_i^2)  ~ 1 for a static point
        # (E = (2n - 3) / 2n, n rays); a moving obstacle's features (crossing motion) fit no static
        # point and their range would be wrong. (Normalised by the current depth instead, a clean
        # track flown at, thesis_speed_15mps at 15 m/s, had median chi 6-10 and failed the test at
        # 40-50 deg of parallax: 6 of its 126 mono obstacle-frames uncovered.)
        res2 = _residual2(Sr, p, pAp)
        chi = res2 / (2.0 * s.feature_sigma_rad ** 2 * np.maximum(d2, 1e-12))
        # the per-feature cut (feature_max_chi) keeps the statistic it was chosen with, the miss
        # over the current depth: stricter for a feature whose older rays were taken from afar
        # (with chi above instead it admitted a corner sliding on mono_straight, 5 % short)
        chi_cut = res2 / (2.0 * (s.feature_sigma_rad * depth) ** 2)
        fit = chi_cut <= s.feature_max_chi
        # a feature whose newest rays left its point ranges nothing (stereo rigs: see the setting)
        if s.feature_slide_memory_s > 0 and ncam > 1:
            slid = self._slid_features(rows, p)
            if slid.any():
                fit &= ~slid
                row_id = np.zeros(fs.size, dtype=np.int64)  # feature id of each store row
                row_id[fs.id_rows] = fs.ids
                self._slid_fids = set(row_id[rows[slid]].tolist())
        # each point's range sigma scaled as the reports' are (k sqrt(s2) sigma_r,f, s2 its noise
        # variance factor, ``_posterior_sigma``): the members are compared with a report in those units
        k_pt = s.mono_point_sigma_k if ncam == 1 else s.stereo_point_sigma_k
        sig_post = _posterior_sigma(sig_r, chi, Sr[:, 17], s.feature_noise_prior_dof)  # (n: fs.n[rows])
        # ... or, when larger, its CURRENT ray's miss over the nominal noise, chi_now = miss^2 /
        # 2 sigma_f^2: a corner that has just slid off its point (onto an occluding edge, a
        # T-junction) misses it now while the mean over its older rays (chi) hardly moves
        sig_post = np.maximum(sig_post, sig_r * np.sqrt(miss2 / (2.0 * s.feature_sigma_rad ** 2)))
        # every track's static member points: range, direction from the body origin, range sigma
        self._members_ls = (g[fit], r[fit], (p.compress(fit, 0) - o) / r[fit][:, None], k_pt * sig_post[fit])
        keep = np.bincount(g, minlength=G)[g] >= n_min
        if not keep.any():
            return
        g, rows, b_now, p, r, sig_r, chi, chi_cut, sig_post = (
            g[keep], rows[keep], b_now.compress(keep, 0), p.compress(keep, 0), r[keep], sig_r[keep],
            chi[keep], chi_cut[keep], sig_post[keep])
        if behind is None:
            chi_med = _group_median(g, chi, G)
        else:
            # the features whose rays meet behind the camera fail the static-point test: each is a
            # failed vote in the median, and when they carry more of the track's ray evidence
            # than the features that meet in front (residual dof of each feature's fit, 2n - 3
            # for n rays: the point took 3) the test fails outright. Over a short window any
            # motion in a feature's epipolar plane (the plane of the flight line and the point)
            # moves its bearing as a static point at another depth would, so a burst of young
            # corners (2-4 rays) on an approaching moving obstacle fits static points at the
            # wrong depth; counted one vote each (and the diverging ones not at all) they ranged
            # val_heldout_moving track 69 at 2.93-2.97 s and val2_heldout_moving track 42 at
            # 2.93 s 2.6-3.0 m against 6.5-6.7 m, 4-9 sigma short. (Not caught: track 69 at 3.00 s
            # and track 52 at 2.93-2.97 s, whose long-lived corners meet in front, chi 97-1450;
            # weighting every feature's chi by its dof catches them but fails static tracks whose
            # corners, tracked over 30-50 deg of parallax, reach chi 10-20: a trade.)
            gb, nb = behind
            chi_med = _group_median(np.concatenate([g, gb]), np.concatenate([chi, np.full(len(gb), np.inf)]),
                                    G)
            w_in = np.bincount(g, weights=np.maximum(2.0 * fs.n[rows] - 3.0, 0.0), minlength=G)
            w_bh = np.bincount(gb, weights=np.maximum(2.0 * nb - 3.0, 0.0), minlength=G)
            chi_med[w_bh > w_in] = np.inf
        if s.feature_point:  # each feature must fit a static point itself (a stereo id mismatch,
            fit = chi_cut <= s.feature_max_chi  # a corner sliding along an edge: not this point)
            if self._slid_fids is not None:  # (nor one whose newest rays left it: _slid_features)
                fit &= ~slid[keep]
            fit &= np.bincount(g[fit], minlength=G)[g] >= n_min
            self._why_unranged(work, cnt, g[fit], f"fewer than {n_min} fit a static point each")
            g, rows, r, sig_r = g[fit], rows[fit], r[fit], sig_post[fit]
            b_now, p = b_now.compress(fit, 0), p.compress(fit, 0)
        b_rep = feats[5]  # (G, 3) first views' bearings
        ang = np.arccos(_dot_rows(b_now, b_rep.take(g, 0)).clip(-1.0, 1.0))
        inner = ang <= _group_median(g, ang, G)[g]
        cnt_in = np.bincount(g[inner], minlength=G)
        if s.feature_inner_half:
            inner |= (cnt_in < n_min)[g]  # too few inner ones: use all
        else:
            inner[:] = True
        if s.feature_point and s.feature_depth_gap_frac > 0:
            inner &= _largest_depth_cluster(g, r, inner, s.feature_depth_gap_frac)
        gi, ri, si = g[inner], r[inner], sig_r[inner]
        n_in = np.bincount(gi, minlength=G)
        point = None
        if s.feature_point:  # the lower-median inner feature's own point and sigma
            # (of the inner ones off the track's outline, when it has two or more: _outline_flags)
            if avoid_ls and len(edge_keys):  # (np.isin's answer: a search in the sorted unique keys)
                key = g * key_n + rows
                at = np.minimum(edge_keys.searchsorted(key), len(edge_keys) - 1)
                cand = inner & (edge_keys[at] != key)
            else:
                cand = inner.copy()
            cand |= inner & (np.bincount(g[cand], minlength=G) < 2)[g]
            gc, rc = g[cand], r[cand]
            sel = _group_lower_median_index(gc, rc, np.bincount(gc, minlength=G), s.feature_point_quantile)
            pick = cand.nonzero()[0][sel]  # into g, r, p, rows
            s_rep = np.hypot(k_pt * sig_r, s.feature_range_floor_frac * r)  # every fit member's report sigma
            if s.feature_near_group and ncam == 1:
                pick = _near_group_choice(g, r, s_rep, pick, n_min, s.feature_depth_gap_frac)
            gp = g[pick]
            z = np.zeros(G)
            z[gp] = r[pick]
            sig = np.zeros(G)
            sig[gp] = s_rep[pick]
            point = np.zeros((G, 3))
            point[gp] = p[pick]
            row_id = np.zeros(fs.size, dtype=np.int64)  # feature id of each store row
            row_id[fs.id_rows] = fs.ids
            point_fid = np.full(G, -1, dtype=np.int64)
            point_fid[gp] = row_id[rows[pick]]
        else:
            z = _group_median(gi, ri, G)
            med_all = _group_median(g, r, G)
            mad_all = _group_median(g, np.abs(r - med_all[g]), G)
            mad = _group_median(gi, np.abs(ri - z[gi]), G)
            s2 = _group_median(gi, si**2, G)
            wa = s.feature_mad_all_weight
            sig = np.sqrt((1.4826 * mad) ** 2 + (wa * 1.4826 * mad_all) ** 2 + s2 / np.maximum(n_in, 1))
            # few features: their MAD understates the spread (and one stray member moves the
            # median), so widen by (1 + k / n)
            sig = sig * (1.0 + s.feature_small_n_inflate / np.maximum(n_in, 1))
        present = np.bincount(g, minlength=G) > 0
        for k in present.nonzero()[0].tolist():
            tr = work[k][0]
            if chi_med[k] > s.feature_static_chi:
                self._feature_why[tr.id] = (f"member features do not range it: they fit no static point "
                                            f"(median chi > {s.feature_static_chi:g}: a moving obstacle?)")
                continue
            zk = float(z[k])
            tr.feature_range = (zk, max(float(sig[k]), 1e-3 * zk), int(n_in[k]))
            if point is not None:
                tr.feature_point = point[k]
                tr.feature_point_fid = int(point_fid[k])

    def _why_unranged(self, work, before: np.ndarray, g: np.ndarray, text: str) -> np.ndarray:
        """The member count (G,) of each track of ``work`` among the (track index) rows g that pass
        one gate of ``_features_batch``; a track that had ``feature_min_count`` members before it
        (counts ``before``) and fewer after gets "member features do not range it: " + text as the
        reason its range is not reported (``_feature_why``, read by ``_process``), unless an
        earlier gate named one."""
        n_min = self.settings.feature_min_count
        now = np.bincount(g, minlength=len(before))
        for k in ((before >= n_min) & (now < n_min)).nonzero()[0].tolist():
            self._feature_why.setdefault(work[k][0].id, f"member features do not range it: {text}")
        return now

    def _slid_features(self, rows: np.ndarray, p: np.ndarray) -> np.ndarray:
        """Mask (K,) of the features (store rows (K,)) whose newest rays no longer meet their
        least-squares point p (K, 3) m in W: the tracked corner slid onto another physical point
        (onto the edge of a nearer obstacle passing in front, along an outline, a T-junction).

        The feature's point p = p_L comes from its rays with the long memory (feature_memory_s).
        The same rays with the short memory tau_s = feature_slide_memory_s (sums A_s, y_s, ...,
        ``_FeatureRays.S_new``) have their own least-squares point p_s = A_s^-1 y_s. If p_L is the
        point the newest rays see, their weighted squared misses rise from p_s to p_L by
            D = (p_L - p_s)^T A_s (p_L - p_s)
        (the cost is quadratic in p with Hessian 2 A_s), and each ray misses the point by
        sigma d_i per axis (sigma = feature_point_sigma_k feature_sigma_rad, the tracked features'
        measured error; d_i its depth to p_L, mean_i d_i^2 = D2_s(p_L), ``_depth2``), so
            T = D / (sigma^2 D2_s(p_L))  ~ chi2_3
        (at most: p_s's weights w_i <= 1 and p_L's own error, nested in p_s's, lower it). The
        test is the geometry's own: A_s holds the parallax the newest rays span (the rig's
        baseline, the flight over tau_s), so along the depth of a point they see over a short
        baseline it allows the large depth error that noise gives there, and a corner that
        jumped to a nearer point shows as the depth the newest rays imply against the stale
        point, while the long-memory fit's own residual (chi) still holds the old rays.
        T > chi2_3(gate_probability): slid. Without the short sums' parallax (det A_s <= 1e-12) no
        test (not slid)."""
        s = self.settings
        Sn = self._features.S_new.take(rows, 0)
        adj, det = _adjugate_det3(Sn[:, 0:9].reshape(len(Sn), 3, 3))
        ok = det > 1e-12
        out = np.zeros(len(rows), dtype=bool)
        if not ok.any():
            return out
        Sn, pL = Sn[ok], p[ok]
        p_s = _einsum("kij,kj->ki", adj[ok], Sn[:, 9:12]) / det[ok][:, None]  # A_s p_s = y_s
        d = pL - p_s
        D = _pAp(Sn, d)  # (p_L - p_s)^T A_s (p_L - p_s)
        d2 = _depth2(Sn, pL, _pAp(Sn, pL))  # the newest rays' mean squared depth to p_L
        sig = s.feature_point_sigma_k * s.feature_sigma_rad
        T = D / np.maximum(sig * sig * d2, 1e-18)
        out[ok] = T > self._chi2_gate(3)
        return out

    def _feature_stereo(self, work, ids: np.ndarray, b_now: np.ndarray, c_now: np.ndarray,
                        b_rep: np.ndarray, edge: np.ndarray) -> None:
        """Stereo ranges of the features one track's first two views share (same id, same frame).

        For each shared feature the two rays (camera a, camera b) are triangulated (midpoint of
        the common perpendicular, range from the body origin, sigma sqrt(2) sigma_f d / sin
        parallax); rays behind a camera, rays whose
        range sigma exceeds stereo_max_rel_sigma of the range or that miss each other by more than
        4 sqrt(2) sigma_f times their depth are dropped. Per track (>= stereo_feature_min_count):
            z = median range of the half nearest the representative ray,
            sigma_z = sqrt((1.4826 MAD)^2 + median sigma_f^2 / n)
        is the fix's noise (fused each frame). The spread of all shared features, 1.4826 MAD_all,
        is the offset between the surface point on the representative ray and the features: the
        same every frame, so filtering does not shrink it; it is kept apart (``struct_sigma_m``),
        weighted by stereo_spread_weight, and added to the reported range sigma in quadrature.
        With feature_point and feature_avoid_outline, the chosen feature (and a kept one) is one
        off the track's outline in both views and inner in both (the farther of its angles from
        the two views' representative rays) when the track has two such features or more (edge
        (M,) bool: each entry of the frame's member features on its view's outline,
        ``_outline_flags``): a corner on an occlusion boundary is a different physical point in
        the two cameras.
        """
        s = self.settings
        # the ids both views of a track list: one intersection of (track, id) keys for all tracks
        # (first occurrences, sorted by track then id: np.intersect1d per track, concatenated)
        ga_l, ia_l, ida_l, ib_l, idb_l = [], [], [], [], []
        rep_b = np.zeros((len(work), 3))  # the second views' representative bearings
        for gi, (_tr, sg, _st) in enumerate(work):
            if len(sg.views) < 2:
                continue
            va, vb = sg.views[0], sg.views[1]
            na, nb = len(va.feature_ids), len(vb.feature_ids)
            if not na or not nb:
                continue
            ga_l.append((gi, na, nb))
            ia_l.append(sg.f0[0])
            ib_l.append(sg.f0[1])
            rep_b[gi] = vb.b_W
            ida_l.append(va.feature_ids)
            idb_l.append(vb.feature_ids)
        if not ga_l:
            return
        gi_a = np.array(ga_l, dtype=np.int64)
        ida, idb = np.concatenate(ida_l), np.concatenate(idb_l)
        ga = gi_a[:, 0].repeat(gi_a[:, 1])
        gb = gi_a[:, 0].repeat(gi_a[:, 2])
        # global index of each entry: its view's offset + its position in the view
        ia_all = ((np.array(ia_l, dtype=np.int64) - (gi_a[:, 1].cumsum() - gi_a[:, 1])).repeat(gi_a[:, 1])
                  + np.arange(len(ida)))
        ib_all = ((np.array(ib_l, dtype=np.int64) - (gi_a[:, 2].cumsum() - gi_a[:, 2])).repeat(gi_a[:, 2])
                  + np.arange(len(idb)))
        lo = min(int(ida.min()), int(idb.min()))
        span = max(int(ida.max()), int(idb.max())) - lo + 1
        if span < 2**40 and len(work) < 2**22:
            _, ka, kb = np.intersect1d((ga << 40) + (ida - lo), (gb << 40) + (idb - lo),
                                       assume_unique=False, return_indices=True)
            ia, ib, gg = ia_all[ka], ib_all[kb], ga[ka]
        else:  # ids too far apart for one key: one intersection per track
            ia_p, ib_p, gg_p = [], [], []
            oa = ob = 0
            for (gi, na, nb), fa, fb in zip(ga_l, ida_l, idb_l, strict=True):
                _, ka, kb = np.intersect1d(fa, fb, assume_unique=False, return_indices=True)
                ia_p.append(ia_all[oa + ka])
                ib_p.append(ib_all[ob + kb])
                gg_p.append(np.full(len(ka), gi, dtype=np.int64))
                oa, ob = oa + na, ob + nb
            ia, ib, gg = np.concatenate(ia_p), np.concatenate(ib_p), np.concatenate(gg_p)
        if not len(ia):
            return
        o = work[0][1].o_W
        c_a, b_a, c_b, b_b = c_now.take(ia, 0), b_now.take(ia, 0), c_now.take(ib, 0), b_now.take(ib, 0)
        # midpoint of the common perpendicular: depths s, t of the closest points c_a + s b_a,
        # c_b + t b_b solve [1 -k; k -1] [s t]^T = [b_a.w, b_b.w], w = c_b - c_a, k = b_a.b_b
        w = c_b - c_a
        k = _einsum("ij,ij->i", b_a, b_b)
        den = 1.0 - k * k  # sin^2(parallax)
        good = den > 1e-12
        den = np.where(good, den, 1.0)
        wa, wb = _einsum("ij,ij->i", b_a, w), _einsum("ij,ij->i", b_b, w)
        dep_a = (wa - k * wb) / den
        dep_b = (k * wa - wb) / den
        q_a = c_a + dep_a[:, None] * b_a
        q_b = c_b + dep_b[:, None] * b_b
        r = np.linalg.norm(0.5 * (q_a + q_b) - o, axis=1)
        miss = np.linalg.norm(q_a - q_b, axis=1)
        depth = np.maximum(dep_a, dep_b)
        # first-order range sigma of a two-ray fix: sqrt(2) sigma_f d / sin(parallax)
        sr = math.sqrt(2.0) * s.feature_sigma_rad * depth / np.sqrt(den)
        ok = (good & (dep_a > 0) & (dep_b > 0) & (sr <= s.stereo_max_rel_sigma * r)
              & (miss <= 4.0 * math.sqrt(2.0) * s.feature_sigma_rad * depth))
        if s.stereo_jump_check and ok.any():
            okk = ok.nonzero()[0]
            ok[okk[self._stereo_jumps(ids[ia][okk], 0.5 * (q_a[okk] + q_b[okk]), sr[okk],
                                      work[0][1].t_s)]] = False
        if not ok.any():
            return
        G = len(work)
        p_mid = (0.5 * (q_a + q_b))[ok]
        fid = ids[ia][ok]
        on_edge = (edge[ia] | edge[ib])[ok]  # on the track's outline in either view
        gg, r, sr, b = gg[ok], r[ok], sr[ok], b_a[ok]
        b_2 = b_b[ok]
        # the shared features' two-ray points, their sigmas in the reports' units (k sigma_r,f)
        self._members_st = (gg, r, (p_mid - o) / r[:, None], s.feature_point_sigma_k * sr)
        self._stereo_pairs = (gg, fid, r, s.feature_point_sigma_k * sr)  # (by feature id: _own_stereo)
        if s.feature_velocity_lag_s > 0:  # (across the ray: each ray misses by sigma_f d, and
            # the midpoint averages the two independent misses: sigma_f d / sqrt(2))
            # (along: from the two cameras' midpoint, the axis of the two-ray point's error)
            u_mid = p_mid - 0.5 * (c_a[ok] + c_b[ok])
            u_mid /= np.sqrt(_dot_rows(u_mid, u_mid))[:, None]
            k_f = s.feature_point_sigma_k  # (the tracked features' measured error over sigma_f)
            self._feature_velocity(work, gg, fid, p_mid, k_f * sr,
                                   k_f * s.feature_sigma_rad * depth[ok] / math.sqrt(2.0), u_mid)
        ang = np.arccos(np.sum(b * b_rep[gg], axis=1).clip(-1.0, 1.0))
        n_min = max(1, s.stereo_feature_min_count)
        cnt = np.bincount(gg, minlength=G)
        inner = ang <= _group_median(gg, ang, G)[gg]
        inner |= (np.bincount(gg[inner], minlength=G) < n_min)[gg]
        gi, ri, si = gg[inner], r[inner], sr[inner]
        n_in = np.bincount(gi, minlength=G)
        if s.feature_point:  # the lower-median inner shared feature's own two-ray point
            # the fix is fused every frame: only its random part (k sigma_r,f) is its noise; the
            # floor (a surface offset of the tracked corners) does not average out over frames and
            # is added to the reported sigma instead (struct_sigma_m). The chosen feature is kept
            # while it stays among the inner ones: the fused point must not jump between corners
            # (that would read as velocity, or be gated); when another is chosen, the filter's
            # position is re-anchored on it (``feature_stereo_anchor``)
            # (off the track's outline, _outline_flags, and inner in both views, the farther of
            # the feature's two angles, when it has two such ones or more: a single one would leave
            # the choice no median to be robust with)
            cand = inner
            if s.feature_avoid_outline:
                ang2 = np.maximum(ang, np.arccos(np.sum(b_2 * rep_b[gg], axis=1).clip(-1.0, 1.0)))
                inner2 = ang2 <= _group_median(gg, ang2, G)[gg]
                inner2 |= (np.bincount(gg[inner2], minlength=G) < n_min)[gg]
                off = inner2 & ~on_edge
                cand = np.where((np.bincount(gg[off], minlength=G) >= 2)[gg], off, inner)
            gc = gg[cand]
            sel = _group_lower_median_index(gc, r[cand], np.bincount(gc, minlength=G),
                                            s.feature_point_quantile)
            cand_idx = cand.nonzero()[0]
            chosen = np.full(G, -1, dtype=np.int64)
            chosen[gc[sel]] = cand_idx[sel]  # (index into the shared features)
            prev = {}
            for k in (cnt >= n_min).nonzero()[0].tolist():
                f_prev = work[k][0].feature_stereo_fid
                if f_prev is not None:
                    prev[(k, f_prev)] = None
            if prev:
                for j, key in zip(cand_idx.tolist(), zip(gc.tolist(), fid[cand].tolist(), strict=True),
                                  strict=True):
                    if key in prev:
                        chosen[key[0]] = j
            for k in (cnt >= n_min).nonzero()[0].tolist():
                j = int(chosen[k])
                zk = float(r[j])
                tr = work[k][0]
                tr.feature_stereo = (zk, max(s.feature_point_sigma_k * float(sr[j]), 1e-3 * zk), int(n_in[k]))
                tr.feature_stereo_point = p_mid[j]
                f_new = int(fid[j])
                if tr.feature_stereo_fid is not None and tr.feature_stereo_fid != f_new:
                    tr.feature_stereo_anchor = True
                tr.feature_stereo_fid = f_new
                tr.struct_sigma_m = s.feature_range_floor_frac * zk
            return
        z = _group_median(gi, ri, G)
        mad = _group_median(gi, np.abs(ri - z[gi]), G)
        s2 = _group_median(gi, si**2, G)
        sig = np.sqrt((1.4826 * mad) ** 2 + s2 / np.maximum(n_in, 1))
        med_all = _group_median(gg, r, G)
        struct = s.stereo_spread_weight * 1.4826 * _group_median(gg, np.abs(r - med_all[gg]), G)
        for k in (cnt >= n_min).nonzero()[0].tolist():
            zk = float(z[k])
            work[k][0].feature_stereo = (zk, max(float(sig[k]), 1e-3 * zk), int(n_in[k]))
            work[k][0].struct_sigma_m = float(struct[k])

    def _stereo_jumps(self, fid: np.ndarray, p_W: np.ndarray, sr: np.ndarray, t_s: float) -> np.ndarray:
        """Which shared features' two-ray points jumped since their last one: (K,) bool for the
        features fid (K,) with this frame's two-ray points p_W (K, 3) m in W and first-order range
        sigmas sr (K,) m at t_s.

        One id is one physical point, so its two-ray point moves only with the obstacle: between
        its last accepted point p' (sigma s', time t') and this one, at most by the obstacle's
        motion, zero-mean with the velocity prior's sigma v (``_velocity_prior_sigma``: the max
        speed, or the drone's, at least 1 m/s) per axis, plus both points' noise in the reports'
        units (k = feature_point_sigma_k):
            |p - p'|^2 > chi2_3(gate_probability) (k^2 (sr^2 + s'^2) + (v (t_s - t'))^2)
        is a jump: one camera's ray of the id is on another physical point now, or was then (a
        stereo-KLT match on another period of a repeated texture, or sliding along an edge). Such
        a point is not used this frame; it is the id's last point for the next frame all the same
        (which of the two was wrong is not known: a lasting change is refused once, not for as
        long as the old point is remembered). (val2_heldout_stereo_flying track 145 at 2.667 s:
        both shared features' points 1.35-1.47 m, one and four frames after 3.6-3.9 m, the obstacle
        at 3.48 m: a stereo fix that put the track at 1.35 m, z^2 1536, then carried.) An id
        without a last point (new, or not seen for lost_after_s) is accepted."""
        s = self.settings
        K = len(fid)
        bad = np.zeros(K, dtype=bool)
        last = self._st_last
        if last is not None and len(last[0]):
            hid, hp, hs, ht = last
            j = np.minimum(hid.searchsorted(fid), len(hid) - 1)
            m = hid[j] == fid
            if m.any():
                jm = j[m]
                v = self._velocity_prior_sigma(t_s) * np.maximum(t_s - ht[jm], 0.0)
                dp = p_W[m] - hp[jm]
                var = s.feature_point_sigma_k ** 2 * (sr[m] ** 2 + hs[jm] ** 2) + v * v
                bad[m.nonzero()[0][_dot_rows(dp, dp) > self._gate3 * var]] = True
        # this frame's points (accepted or not) become their ids' last ones; ids unseen for
        # lost_after_s are dropped
        nid, sel = _unique_first(fid)
        if last is not None and len(last[0]):
            hid, hp, hs, ht = last
            old = (t_s - ht <= s.lost_after_s) & ~_isin(hid, nid)
            nid = np.concatenate([hid[old], nid])
            order = nid.argsort(kind="stable")
            self._st_last = (nid[order], np.concatenate([hp[old], p_W[sel]])[order],
                             np.concatenate([hs[old], sr[sel]])[order],
                             np.concatenate([ht[old], np.full(len(sel), t_s)])[order])
        else:
            self._st_last = (nid, p_W[sel].copy(), sr[sel].copy(), np.full(len(sel), t_s))
        return bad

    def _feature_velocity(self, work, gg: np.ndarray, fid: np.ndarray, p_mid: np.ndarray,
                          sr: np.ndarray, st: np.ndarray, u: np.ndarray) -> None:
        """Velocity of each stereo track from its own shared features' two-ray points (gg (K,)
        work index, fid (K,) feature ids, p_mid (K, 3) points in W, sr (K,) their sigmas along the
        viewing ray u (K, 3) (unit, W) and st (K,) across it, m).

        A two-ray point's covariance is C = sr^2 u u^T + st^2 (I - u u^T): along the ray the
        stereo range sigma (sqrt(2) s_f d / sin parallax), across it s_f d / sqrt(2) (the midpoint
        of two rays that each miss by s_f d), ~40x smaller at 4 m with a 0.30 m baseline; s_f =
        feature_point_sigma_k sigma_f, a tracked feature's measured error (as for the stereo
        fix). Every ``feature_velocity_lag_s`` the points of the ids seen then and now (>= 2) give
        v_i = (p_i(t) - p_i(t_ref)) / (t - t_ref) (the thesis's binocular speed, sec. 3.2.2: two
        stereo fixes 0.1 s apart, here per physical point).
        They are reduced in the track's ray frame Q = [a, e1, e2] (a the mean viewing direction,
        [e1, e2] = _ttangent_basis(a)'s basis), where C is nearly diagonal:
            w_i = Q^T v_i,   w = per-axis median of the w_i,
            s2_ik = q_k^T (C_i(t_ref) + C_i(t)) q_k / dt^2,   s2_k = median_i s2_ik,
            R_Q = diag(s2_k c_n / n + q dt / 3)
        (c_n = n Var(median) / sigma^2 of n normal samples, ``median_variance_factor``: 1.29 for
        6, pi / 2 for many; q dt / 3: the mean velocity over dt against the velocity at t under
        white acceleration of PSD q = max_accel^2 tau, the moving filter's process model). On an
        axis where the features do not move alike at that noise, sum_i (w_ik - w_k)^2 / s2_ik >
        chi2_(n-1)(gate_probability) (members of another object or of the background, or more noise
        than sigma_f), s2_k is max(s2_k, (1.4826 MAD_k)^2) instead. v = Q w, R = Q R_Q Q^T.
        References are staggered: every frame's points are measured against the newest reference
        at least one lag old and then become a reference themselves, so from one lag on every
        frame gives a measurement and each frame's points are used twice, once as an end and once
        as a start (with one reference a lag, as before 2026-11-22, a measurement came every lag
        plus one frame, and the frames in between were not used). Two measurements that share a
        frame (one's end, the other's start) have negatively correlated point noise; fused as
        independent by filters whose gains are positive, that is an upper bound of the fused
        variance, and a chain of them telescopes into the displacement over the whole span
        (the longer baseline that makes a velocity sure). The process part of overlapping
        intervals is positively correlated instead: the m references pending (about lag / frame
        interval) scale q by m in R (for a Brownian velocity the correlations of intervals shifted
        by 1, 2, ... of m frames sum to about m - 0.7). Measured by replaying one recording of the
        29 accuracy scenes (2026-11-22): the demo scene's stereo speed error 11.29 -> 5.15 %.

        Each measurement also updates the track's velocity evidence ``vel_acc`` (v, P, t), a
        3-D constant-velocity filter of these measurements alone (process noise as the moving
        filter's, q = max_accel^2 tau), held at the intervals' midpoints t - dt / 2 (where the
        mean velocity differs from the velocity by only q dt / 12, which replaces q dt / 3 in R
        there); ``vel_moving``: it rejects zero velocity, v^T P^-1 v > chi2_3(gate_probability)
        with P grown to each frame (re-decided every frame, ``_evidence_now``), i.e. the obstacle
        moves and its features' static least-squares points would be wrong. A track's one chosen
        point would jump between corners; the features' own displacements do not."""
        s = self.settings
        t_s = work[0][1].t_s
        lag = s.feature_velocity_lag_s
        # each track's shared features sorted by id (ids are unique within a track)
        order = np.lexsort((fid, gg))
        gs = gg[order]
        starts = np.diff(gs, prepend=-1).nonzero()[0]  # each track's run in order
        ends = np.append(starts[1:], len(gs))
        f_s, P_s, S_s, T_s, U_s = fid[order], p_mid[order], sr[order], st[order], u[order]
        due: list[tuple[_Track, tuple, int, int]] = []  # (track, its reference, run start, end)
        m_due: list[int] = []  # the references each due track has pending, this frame's included
        for gi, a0, a1 in zip(gs[starts].tolist(), starts.tolist(), ends.tolist(), strict=True):
            tr = work[gi][0]
            # one reference per frame (staggered): this frame's points are measured against the
            # newest reference at least one lag old, then become a reference themselves; that one
            # and older ones are dropped, and those older than 3 lags
            refs = [r for r in (tr.vel_ref or ()) if t_s - r[0] <= 3.0 * lag]
            k_due = -1
            for k, r in enumerate(refs):
                if t_s - r[0] >= lag - 1e-9:
                    k_due = k
            ref = refs[k_due] if k_due >= 0 else None
            refs = refs[k_due + 1:]
            if a1 - a0 >= 2:  # (a reference sharing a single id measures nothing)
                refs.append((t_s, f_s[a0:a1], P_s[a0:a1], S_s[a0:a1], T_s[a0:a1], U_s[a0:a1]))
            tr.vel_ref = refs or None
            if ref is not None:
                due.append((tr, ref, a0, a1))
                m_due.append(max(1, len(refs)))
        if not due:
            return
        # the ids each due track shares with its reference: one intersection of (track, id) keys
        # (as np.intersect1d per track; within a track both id lists are sorted and unique)
        D = len(due)
        n_ref = np.array([len(ref[1]) for _tr, ref, _a0, _a1 in due], dtype=np.int64)
        n_now = np.array([a1 - a0 for _tr, _ref, a0, a1 in due], dtype=np.int64)
        f_ref = np.concatenate([ref[1] for _tr, ref, _a0, _a1 in due])
        now = np.concatenate([np.arange(a0, a1) for _tr, _ref, a0, a1 in due])
        d_ref = np.arange(D).repeat(n_ref)
        d_now = np.arange(D).repeat(n_now)
        lo = min(int(f_ref.min()), int(f_s[now].min()))
        span = max(int(f_ref.max()), int(f_s[now].max())) - lo + 1
        if span < 2**40 and D < 2**22:
            _, ka, kb = np.intersect1d((d_ref << 40) + (f_ref - lo), (d_now << 40) + (f_s[now] - lo),
                                       assume_unique=True, return_indices=True)
        else:  # ids too far apart for one key: one intersection per track
            ka_l, kb_l = [], []
            oa = ob = 0
            for k, (_tr, ref, a0, a1) in enumerate(due):
                _, a, b = np.intersect1d(ref[1], f_s[a0:a1], assume_unique=True, return_indices=True)
                ka_l.append(a + oa)
                kb_l.append(b + ob)
                oa, ob = oa + int(n_ref[k]), ob + int(n_now[k])
            ka, kb = np.concatenate(ka_l), np.concatenate(kb_l)
        dk = d_ref[ka]  # (the pairs in (track, id) order)
        n = np.bincount(dk, minlength=D)
        ok = n >= 2
        if not ok.any():
            return
        keep = ok[dk]
        ka, kb, dk = ka[keep], kb[keep], dk[keep]
        R_P = np.concatenate([ref[2] for _tr, ref, _a0, _a1 in due])[ka]
        R_S = np.concatenate([ref[3] for _tr, ref, _a0, _a1 in due])[ka]
        R_T = np.concatenate([ref[4] for _tr, ref, _a0, _a1 in due])[ka]
        R_U = np.concatenate([ref[5] for _tr, ref, _a0, _a1 in due])[ka]
        # the due tracks with >= 2 shared ids, renumbered 0..G-1
        dk = (ok.cumsum() - 1)[dk]
        due = [d for d, o in zip(due, ok.tolist(), strict=True) if o]
        m_ov = np.array(m_due, dtype=float)[ok]
        n = n[ok]
        G = len(due)
        start = n.cumsum() - n
        dt = np.array([t_s - ref[0] for _tr, ref, _a0, _a1 in due])
        kb = now[kb]
        N_P, N_S, N_T, N_U = P_s[kb], S_s[kb], T_s[kb], U_s[kb]
        # the ray frame Q = [a, e1, e2] of each track (a the mean viewing direction, _ttangent_basis's)
        a = np.add.reduceat(N_U, start, axis=0)
        a /= np.sqrt(_dot_rows(a, a))[:, None]
        e = np.zeros_like(a)
        e[np.arange(G), np.argmin(np.abs(a), axis=1)] = 1.0
        e1 = _cross(a, e)
        e1 /= np.sqrt(_dot_rows(e1, e1))[:, None]
        Q = np.stack([a, e1, _cross(a, e1)], axis=2)  # (G, 3, 3), columns a, e1, e2
        Qk = Q[dk]
        W = _einsum("ki,kij->kj", (N_P - R_P) / dt[dk][:, None], Qk)  # per-feature velocities, ray frame
        # per-axis medians over each track's features: its rows padded with +inf and sorted
        m = int(n.max())
        pos = np.arange(len(dk)) - start[dk]
        lo_i, hi_i = (n - 1) // 2, n // 2
        rg = np.arange(G)

        def group_median_cols(X: np.ndarray) -> np.ndarray:  # (rows, 3) -> (G, 3), np.median per track
            pad = np.full((G, m, 3), np.inf)
            pad[dk, pos] = X
            pad.sort(axis=1)
            lo_v, hi_v = pad[rg, lo_i], pad[rg, hi_i]
            return np.where((n % 2 == 1)[:, None], hi_v, (lo_v + hi_v) / 2.0)

        w = group_median_cols(W)
        # q_k^T C_i q_k of both points: sr^2 (q.u)^2 + st^2 (1 - (q.u)^2)
        c2 = _einsum("ki,kij->kj", R_U, Qk) ** 2
        var = (R_S * R_S)[:, None] * c2 + (R_T * R_T)[:, None] * (1.0 - c2)
        c2 = _einsum("ki,kij->kj", N_U, Qk) ** 2
        var += (N_S * N_S)[:, None] * c2 + (N_T * N_T)[:, None] * (1.0 - c2)
        var /= (dt * dt)[dk][:, None]
        var_k = group_median_cols(var)
        # features that do not move alike at that noise (chi-square test of their spread at the
        # gate probability: another object's or the background's members, or more noise than
        # sigma_f): their spread (1.4826 MAD) is the noise instead, when larger
        res = W - w[dk]
        chi = np.add.reduceat(res * res / var, start, axis=0)  # (G, 3)
        gate = np.array([self._chi2_gate(k - 1) for k in n.tolist()])[:, None]
        wide = chi > gate
        if wide.any():
            mad2 = (1.4826 * group_median_cols(np.abs(res))) ** 2
            var_k = np.where(wide, np.maximum(mad2, var_k), var_k)
        # (+ q dt / 12 on each axis: the displacement measures the mean velocity over dt, which
        # differs from the velocity at the interval's midpoint by that much under the filter's
        # white acceleration, PSD q = max_accel^2 tau; q dt / 3 from the velocity at its end;
        # the staggered intervals overlap: q taken m times, m the references pending with this
        # frame's, about lag / frame interval: see the docstring)
        q = s.max_accel_mps2**2 * s.accel_time_s * m_ov
        rq = var_k * (np.array([median_variance_factor(k) for k in n.tolist()]) / n)[:, None]
        v = _einsum("gij,gj->gi", Q, w)
        QT = Q.transpose(0, 2, 1)
        R_end = (Q * (rq + (q * dt / 3.0)[:, None])[:, None, :]) @ QT
        R_mid = (Q * (rq + (q * dt / 12.0)[:, None])[:, None, :]) @ QT
        for k, (tr, _ref, _a0, _a1) in enumerate(due):
            tr.feature_velocity = (v[k], R_end[k])
        self._velocity_evidence([tr for tr, _ref, _a0, _a1 in due], v, R_mid, (t_s - 0.5 * dt).tolist())

    def _chi2_gate(self, k: int) -> float:
        """chi2_k(gate_probability), cached per degrees of freedom k >= 1."""
        key = (self.settings.gate_probability, max(int(k), 1))
        g = _CHI2_PPF.get(key)
        if g is None:  # (chi2_ppf bisects; kept per process, for every fusion of a run)
            g = _CHI2_PPF[key] = chi2_ppf(*key)
        return g

    def _velocity_evidence(self, trs: list[_Track], V: np.ndarray, R: np.ndarray, T: list[float]) -> None:
        """Fuse feature velocities V (K, 3) m/s, covariances R (K, 3, 3), measured at T (K,) s, one
        per track of trs (distinct tracks), into each track's velocity evidence ``vel_acc`` (a
        constant-velocity filter: P += q dt I between measurements, q = max_accel_mps2^2
        accel_time_s, the moving filter's process noise, ``_grown_all``; then the Kalman update with
        H = I: K = P0 (P0 + R)^-1, x = x0 + K (v - x0), P = (I - K) P0 made symmetric). A track
        without evidence starts from its measurement. All tracks at once: numpy's stacked inv and
        matmul make LAPACK's and BLAS's per-matrix calls, so the numbers are one track's at a
        time. ``vel_moving`` is decided from the evidence each frame (``_evidence_now``)."""
        old = [k for k, tr in enumerate(trs) if tr.vel_acc is not None]
        for k, tr in enumerate(trs):
            if tr.vel_acc is None:
                tr.vel_acc = (V[k], R[k], T[k])
        if not old:
            return
        e = [trs[k].vel_acc for k in old]
        X0 = np.array([x for x, _P, _t in e])
        P0 = self._grown_all(e, [T[k] for k in old])
        K = P0 @ np.linalg.inv(P0 + R[old])
        x = X0 + (K @ (V[old] - X0)[:, :, None])[:, :, 0]
        P = P0 - K @ P0
        P = 0.5 * (P + P.transpose(0, 2, 1))
        for j, k in enumerate(old):
            trs[k].vel_acc = (x[j], P[j], T[k])

    def _grown(self, e: tuple, t_s: float) -> np.ndarray:
        """The covariance (3, 3) m^2/s^2 of velocity evidence e = (v, P, t_e) grown to t_s:
        P + q (t_s - t_e) I, q = max_accel_mps2^2 accel_time_s (``_grown_all``: several at once)."""
        q = self.settings.max_accel_mps2**2 * self.settings.accel_time_s
        return e[1] + _EYE3 * (q * max(t_s - e[2], 0.0))

    def _grown_all(self, es: list[tuple], T: list[float]) -> np.ndarray:
        """``_grown`` of several velocity evidences es = [(v, P, t_e), ...], each to its time in T
        (s): (K, 3, 3) m^2/s^2, the same numbers one at a time."""
        q = self.settings.max_accel_mps2**2 * self.settings.accel_time_s
        age = np.array([max(t - e[2], 0.0) for e, t in zip(es, T, strict=True)])
        return np.array([e[1] for e in es]).reshape(len(es), 3, 3) + _EYE3 * (q * age)[:, None, None]

    def _evidence_now(self, trs: list[_Track], t_s: float) -> tuple[np.ndarray, list[bool]]:
        """The velocity evidence ``vel_acc`` = (v, P, t_e) of each track in trs (all with one)
        grown to t_s: P(t_s) = P + q (t_s - t_e) I (q = max_accel_mps2^2 accel_time_s, the
        evidence filter's process noise), (K, 3, 3) m^2/s^2, and whether it rejects zero velocity
        now, v^T P(t_s)^-1 v > chi2_3(gate_probability) (K bools): evidence that is no longer
        renewed stops deciding "moving" as its covariance grows."""
        V = np.array([tr.vel_acc[0] for tr in trs]).reshape(len(trs), 3)
        P = self._grown_all([tr.vel_acc for tr in trs], [t_s] * len(trs))
        chi = _einsum("ki,ki->k", V, np.linalg.solve(P, V[:, :, None])[:, :, 0])
        return P, (chi > self._gate3).tolist()

    def _filter_moving(self, tr: _Track, t_s: float) -> bool:
        """Whether a moving-hypothesis track's own filter rejects zero velocity at t_s:
        v^T (P_vv + q dt I)^-1 v > chi2_3(gate_probability), with v, P_vv its state's velocity and
        covariance (m/s, m^2/s^2, W), grown by the moving process noise q = max_accel^2 tau over the
        dt = t_s - t_kf since (the ``vel_moving`` test on the filter instead of the velocity
        evidence: a track whose shared features are too few for feature velocities still measures
        its motion from successive stereo fixes). A moving obstacle's features can fit static
        points at a wrong depth (motion along the epipolar planes of the drone's baseline: the
        monocular ambiguity), so such a track is not ranged from static points."""
        if not tr.moving or tr.kf is None:
            return False
        return self._rejects_zero((tr.kf.x[3:], tr.kf.P[3:, 3:], tr.t_kf), t_s)

    def _stereo_from_features(self, tr: _Track, sg: _Sighting):
        """The feature stereo fix: the median shared feature's point (``feature_point``) or the
        feature stereo range as a point on the first view's representative ray (see
        _point_on_ray): (p_W (3,), R (3, 3))."""
        z, sig, _n = tr.feature_stereo
        if tr.feature_stereo_point is not None:
            p = tr.feature_stereo_point
            return p, _ray_covariance(p - sg.o_W, sig, sg.views[0].sigma_rad)
        return self._point_on_ray(sg, z, sig)

    def _point_on_ray(self, sg: _Sighting, z: float, sig: float):
        """Point on the first view's ray c + d b at range z from the body origin o, and its
        covariance (sig along the range, the bearing sigma across):
            d = -(b.w) + sqrt((b.w)^2 - |w|^2 + z^2),  w = c - o."""
        v = sg.views[0]
        w = v.c_W - sg.o_W
        bw = float(v.b_W @ w)
        disc = bw * bw - float(w @ w) + z * z
        d = -bw + math.sqrt(disc) if disc > 0 else z
        p = v.c_W + d * v.b_W
        return p, _ray_covariance(p - sg.o_W, sig, v.sigma_rad)

    def _set_from_features_batch(self, batch: list[tuple[_Track, _Sighting]], fc: _FrameContext) -> None:
        """(Re)set the point of every track its member features range on its representative ray at
        the feature range (or at the median feature's own point, ``feature_point``), all tracks at
        once, then apply the bounds of static-hypothesis ones.

        The feature estimate is cumulative (all rays of every feature), so it replaces the state
        rather than being fused again each frame (no double counting). The point is where the ray
        c + d b of the first view is at range z from the body origin o:
            d = -(b.w) + sqrt((b.w)^2 - |w|^2 + z^2),  w = c - o,   p = c + d b,
        with covariance R = sig^2 u u^T + (|p - o| sigma_b)^2 (I - u u^T) (``_ray_covariance``) and
        the velocity prior static_velocity_sigma_mps (velocity 0).
        """
        s = self.settings
        K = len(batch)
        v0 = [sg.views[0] for _tr, sg in batch]
        c = np.array([v.c_W for v in v0])
        b = np.array([v.b_W for v in v0])
        zs = np.array([tr.feature_range[:2] for tr, _sg in batch])
        z, sig = zs[:, 0], zs[:, 1]
        sb = np.array([v.sigma_rad for v in v0])
        o = fc.o_W
        w = c - o
        bw = b[:, 0] * w[:, 0] + b[:, 1] * w[:, 1] + b[:, 2] * w[:, 2]
        disc = bw * bw - (w[:, 0] * w[:, 0] + w[:, 1] * w[:, 1] + w[:, 2] * w[:, 2]) + z * z
        d = np.where(disc > 0, -bw + np.sqrt(np.maximum(disc, 0.0)), z)
        X = np.zeros((K, 6))
        X[:, :3] = c + d[:, None] * b
        own = [k for k, (tr, _sg) in enumerate(batch) if tr.feature_point is not None]
        if own:  # feature_point: the median member feature's own point instead
            X[own, :3] = np.array([batch[k][0].feature_point for k in own])
        P = np.zeros((K, 6, 6))
        P[:, :3, :3] = _ray_covariances(X[:, :3] - o, sig, sb)
        P[:, 3, 3] = P[:, 4, 4] = P[:, 5, 5] = s.static_velocity_sigma_mps**2
        # a moving-hypothesis track whose features fit static points: its velocity is assumed
        # (0), not measured, so it keeps the velocity prior's sigma (its report's velocity, if any,
        # is its velocity evidence: see _reports)
        mov = [k for k, (tr, _sg) in enumerate(batch) if tr.moving]
        if mov:
            vp = self._velocity_prior_sigma(fc.t_s) ** 2
            P[mov, 3, 3] = P[mov, 4, 4] = P[mov, 5, 5] = vp
            for k in mov:
                batch[k][0].vel_assumed = True
        rel = X[:, :3] - o
        r = np.sqrt(_dot_rows(rel, rel)).tolist()  # (np.linalg.norm's values)
        v_sigma = s.static_velocity_sigma_mps
        for k, (tr, sg) in enumerate(batch):
            tr.struct_sigma_m = 0.0  # (sig has the features' spread already)
            tr.pair_tested = None  # (the features' chi tests it)
            tr.point_fid = tr.feature_point_fid  # (None: on the representative ray, no support rule)
            tr.point_is_feature = tr.point_fid is not None
            tr.feature_stereo_anchor = True  # (a static feature's point, not the stereo one)
            if tr.kf is None:
                tr.kf = self._new_kf(X[k, :3], P[k, :3, :3], v_sigma)
            else:  # the state is replaced: no prediction needed
                tr.kf.x = X[k]
                tr.kf.P = P[k]
            tr.t_kf = sg.t_s
            tr.t_ranged = sg.t_s
            tr.gated_run = 0
            tr.reason = None
            tr.sources.add("mono")
            if len(sg.views) >= 2:
                tr.sources.add("stereo")
            tr.bounded_now = False
            bd = tr.bounds
            if not tr.moving and bd is not None and (
                    r[k] < bd.range_min_m or (bd.range_max_m is not None and r[k] > bd.range_max_m)):
                self._apply_bounds(tr, sg)  # stereo measures range itself; the bounds rest on an
            tr.history.append(sg)           # assumed max speed
            tr.last_seen_t = sg.t_s
            tr.last_views = sg.views
            tr.cameras = (sg.views[0].camera,) if len(sg.views) == 1 else tuple([v.camera for v in sg.views])

    # ---------------------------------------------------------------------------------- filter
    def _new_kf(self, p_W: np.ndarray, P_pp: np.ndarray, v_sigma: float) -> ExtendedKalmanFilter:
        kf = _new_ekf()
        kf.x = np.concatenate([p_W, np.zeros(3)])
        kf.P = np.zeros((6, 6))
        kf.P[:3, :3] = P_pp
        kf.P[3:, 3:] = np.eye(3) * v_sigma**2
        return kf

    def _velocity_prior_sigma(self, t_s: float) -> float:
        v_sigma = self.settings.velocity_prior_sigma_mps
        if v_sigma is None:
            v_sigma = max(self._max_speed(t_s, t_s), 1.0)
        return float(v_sigma)

    def _to_moving(self, tr: _Track, t_s: float) -> None:
        """Switch a static-hypothesis track to the moving one: velocity prior from the max speed."""
        v_sigma = self._velocity_prior_sigma(t_s)
        tr.kf.x[3:] = 0.0
        tr.kf.P[:3, 3:] = 0.0
        tr.kf.P[3:, :3] = 0.0
        tr.kf.P[3:, 3:] = np.eye(3) * v_sigma**2
        tr.moving = True
        tr.pair_tested = None

    def _init_stereo(self, tr: _Track, sg: _Sighting, stereo) -> None:
        p, R = stereo
        tr.kf = self._new_kf(p, R, self._velocity_prior_sigma(sg.t_s))
        tr.pair_tested = None
        tr.feature_stereo_anchor = tr.feature_stereo is None  # (the representative rays' point)
        tr.point_fid = None  # (a stereo point: re-measured every frame both cameras see it)
        tr.point_is_feature = False
        tr.t_kf = sg.t_s
        tr.moving = True
        # from its features' stereo points: the velocity waits for their displacements
        # (_feature_velocity); successive fixes of one chosen corner jump between corners
        tr.vel_assumed = tr.feature_stereo is not None and self.settings.feature_velocity_lag_s > 0
        tr.sources.add("stereo")
        tr.t_ranged = sg.t_s
        tr.gated_run = 0
        tr.reason = None

    def _init_mono(self, tr: _Track, sg: _Sighting, past: _Sighting, tri: geometry.Triangulation) -> None:
        vb = sg.views[0]
        va = past.views[0]
        sigma = math.sqrt(0.5 * (va.sigma_rad**2 + vb.sigma_rad**2))
        R = _ray_covariance(tri.p - vb.c_W, tri.range_sigma_m, sigma)
        tr.kf = self._new_kf(tri.p, R, self.settings.static_velocity_sigma_mps)
        tr.pair_tested = False  # (until a further bearing agrees with it: the replay's, a later frame's)
        tr.feature_stereo_anchor = True  # (on the representative ray)
        # its support: the member feature whose current ray passes nearest the triangulated point
        tr.point_is_feature = False
        tr.point_fid = None
        if len(vb.feature_ids):
            d = tri.p - vb.c_W
            cos_f = vb.feature_b_W @ (d / np.linalg.norm(d))
            j = int(np.argmax(cos_f))
            tr.point_fid = int(vb.feature_ids[j])
            # the representative rays are centroids of members that come and go: when even the
            # nearest member's ray misses their point by more than sqrt(gate) k sigma_f (the
            # chi-square gate on a feature ray's bearing sigma alone, without the state's own
            # covariance), no tracked point is at that range: not reported (mono_straight track
            # 40: ranged 10.9 m with its one member 4 deg away, the obstacle on that bearing at
            # 6.5 m)
            s = self.settings
            ang = math.acos(min(max(float(cos_f[j]), -1.0), 1.0))
            if ang > math.sqrt(self._gate2) * s.feature_point_sigma_k * s.feature_sigma_rad:
                tr.kf = None
                tr.point_fid = None
                tr.reason = "no member feature on the representative rays' triangulated point"
                return
        tr.t_kf = past.t_s
        tr.moving = False
        tr.gated_run = 0
        # replay the sightings between the two that were triangulated (stationary hypothesis), each
        # weighed as _process weighs a frame's update (``_repeat_scale``: its time since the one
        # before; at 100 fps a second of replay is otherwise 3.3x the evidence of one at 30 fps)
        t_prev = past.t_s
        for h in tr.history:
            if past.t_s < h.t_s < sg.t_s:
                self._predict(tr, h.t_s)
                c = self._repeat_scale(t_prev, h.t_s)
                for v in self._mono_views(tr, h):
                    self._bearing_update(tr, v, c)
                t_prev = h.t_s
        self._predict(tr, sg.t_s)
        c = self._repeat_scale(t_prev, sg.t_s)  # (as this frame's update in _process would be)
        for v in self._mono_views(tr, sg)[1:]:  # further cameras of this frame (the first one was
            self._bearing_update(tr, v, c)      # triangulated)
        tr.sources.add("mono")
        tr.reason = None

    def _predict(self, tr: _Track, t_s: float) -> None:
        dt = t_s - tr.t_kf
        if dt <= 0:
            return
        key = (dt, tr.moving)
        FQ = self._FQ_cache.get(key)
        if FQ is None:  # (one dt per frame for most tracks: F and Q are shared, never written)
            a = self.settings.max_accel_mps2 if tr.moving else self.settings.static_accel_mps2
            q = a * a * self.settings.accel_time_s  # PSD, m^2/s^3: sqrt(q tau) = a tau
            F = np.eye(6)
            F[:3, 3:] = np.eye(3) * dt  # p' = p + v dt
            Q = np.zeros((6, 6))
            Q[:3, :3] = np.eye(3) * q * dt**3 / 3.0
            Q[:3, 3:] = Q[3:, :3] = np.eye(3) * q * dt**2 / 2.0
            Q[3:, 3:] = np.eye(3) * q * dt
            F.setflags(write=False)
            Q.setflags(write=False)
            FQ = self._FQ_cache[key] = (F, Q)
        tr.kf.F, tr.kf.Q = FQ
        _ekf_predict(tr.kf)
        tr.t_kf = t_s

    def _gated_update(self, tr: _Track, y: np.ndarray, H: np.ndarray, R: np.ndarray, gate: float) -> bool:
        """Fuse residual y with Jacobian H and noise R unless NIS = y^T S^-1 y > gate; returns whether
        fused. filterpy's update forms S = H P H^T + R and its inverse once; the NIS is read from
        them after the update, and a gated update is undone (x and P restored)."""
        kf = tr.kf
        x0, P0 = kf.x, kf.P  # (filterpy's update binds new arrays: these stay the prior)
        # filterpy EKF update with the residual already formed about the linearisation point:
        # z = y, h(x) = 0 (bearing) / the same residual for a linear measurement.
        if not _ekf_update(kf, y, H, R):  # S singular (zero noise on a zero-variance direction):
            tr.gated += 1  # the NIS is undefined; the measurement is rejected like a gated one
            tr.gated_run += 1
            return False
        yv = kf.y
        nis = float(yv @ kf.SI @ yv)
        if not math.isfinite(nis) or nis > gate:
            kf.x, kf.P = x0, P0
            tr.gated += 1
            tr.gated_run += 1
            return False
        tr.nis, tr.innovation = nis, yv
        tr.gated_run = 0
        return True

    def _bearing_update(self, tr: _Track, v: _View, scale: float = 1.0) -> bool:
        """Fuse the ray of view v (``_bearing_fuse``); a state of ``_init_mono`` records whether this
        test of it passed (``pair_tested``)."""
        ok = self._bearing_fuse(tr, v, scale)
        if tr.pair_tested is not None:
            tr.pair_tested = ok
        return ok

    def _bearing_fuse(self, tr: _Track, v: _View, scale: float) -> bool:
        """Fuse the ray of view v (its sigma_rad; R scaled by scale >= 1: ``_repeat_scale``)."""
        x = tr.kf.x
        c, b = v.c_W, v.b_W
        d = (float(x[0]) - float(c[0]), float(x[1]) - float(c[1]), float(x[2]) - float(c[2]))
        rho = math.sqrt(_tdot(d, d))
        if rho < 1e-6:
            tr.gated += 1
            tr.gated_run += 1
            return False
        u = (d[0] / rho, d[1] / rho, d[2] / rho)
        bt = (float(b[0]), float(b[1]), float(b[2]))
        cos_ang = _tdot(u, bt)
        if cos_ang < 0.5:  # more than 60 degrees off the predicted ray: not this obstacle
            tr.gated += 1
            tr.gated_run += 1
            return False
        e1, e2 = _ttangent_basis(u)
        # gnomonic coordinates of the measured ray about the predicted one: y = E^T b / (u . b)
        y = np.array((_tdot(e1, bt) / cos_ang, _tdot(e2, bt) / cos_ang))
        H = np.array((  # d(gnomonic)/dp at the prediction: [E^T / rho, 0]
            (e1[0] / rho, e1[1] / rho, e1[2] / rho, 0.0, 0.0, 0.0),
            (e2[0] / rho, e2[1] / rho, e2[2] / rho, 0.0, 0.0, 0.0)))
        s2 = v.sigma_rad * v.sigma_rad * scale
        R = np.array(((s2, 0.0), (0.0, s2)))
        return self._gated_update(tr, y, H, R, self._gate2)

    def _point_update(self, tr: _Track, p_W: np.ndarray, R: np.ndarray, scale: float = 1.0) -> bool:
        """Fuse a point p_W (3,) W of covariance R (3, 3) scaled by scale >= 1 (``_repeat_scale``)."""
        y = p_W - tr.kf.x[:3]  # z - H x,  H = [I 0]
        return self._gated_update(tr, y, _H_POS, R * scale if scale != 1.0 else R, self._gate3)

    def _anchor_position(self, tr: _Track, p_W: np.ndarray, R: np.ndarray) -> None:
        """Put the filter's position on the feature stereo point p_W (3,) W, covariance R (3, 3),
        keeping its velocity (x_p = p, P_pp = R, no position-velocity correlation): the state stood
        for another point of the object (another corner, the static features' median point, the
        representative ray), whose offset to this one is not motion."""
        kf = tr.kf
        kf.x = kf.x.copy()
        kf.x[:3] = p_W
        kf.P = kf.P.copy()
        kf.P[:3, :3] = R
        kf.P[:3, 3:] = 0.0
        kf.P[3:, :3] = 0.0
        tr.feature_stereo_anchor = False

    def _velocity_update(self, tr: _Track, v_W: np.ndarray, R: np.ndarray) -> bool:
        """Fuse a measured velocity v_W (3,) m/s in W with covariance R (3, 3): z = v,
        H = [0 I] (gated like a stereo point, 3 dof). A track whose velocity was assumed (its state
        was replaced by a static feature point) takes its velocity evidence (``vel_acc``, which
        holds this measurement) as its velocity instead (x_v, P_vv from it, no position-velocity
        correlation): the jump from that point to the stereo fixes has been read as velocity by
        then."""
        if tr.vel_assumed:
            self._adopt_velocity_evidence(tr, (v_W, R))
            return True
        return self._gated_update(tr, v_W - tr.kf.x[3:], _H_VEL, R, self._gate3)  # H = [0 I]

    def _adopt_velocity_evidence(self, tr: _Track, meas: tuple | None = None) -> None:
        """Set the velocity of a track whose velocity was assumed (x_v, P_vv) from its velocity
        evidence ``vel_acc`` (which holds every feature velocity so far; P += q dt I since its
        last one, q = max_accel^2 tau), else from the measurement meas = (v (3,), R (3, 3)); no
        position-velocity correlation."""
        kf = tr.kf
        if tr.vel_acc is not None:
            v, P = tr.vel_acc[0], self._grown(tr.vel_acc, tr.t_kf)
        else:
            v, P = meas
        kf.x = kf.x.copy()
        kf.x[3:] = v
        kf.P = kf.P.copy()
        kf.P[:3, 3:] = 0.0
        kf.P[3:, :3] = 0.0
        kf.P[3:, 3:] = P
        tr.vel_assumed = False

    def _apply_bounds(self, tr: _Track, sg: _Sighting) -> None:
        """Range pseudo-measurement at the violated bound (soft projection into the interval)."""
        b = tr.bounds
        if b is None:
            return
        d = tr.kf.x[:3] - sg.o_W
        r = _norm(d)
        if r < 1e-9:
            return
        if r < b.range_min_m:
            target = b.range_min_m
        elif b.range_max_m is not None and r > b.range_max_m:
            target = b.range_max_m
        else:
            return
        H = np.zeros((1, 6))
        H[0, :3] = d / r  # d|p - o|/dp
        R = np.array([[(self.settings.bounds_pseudo_sigma_frac * max(target, 1e-3)) ** 2]])
        y = np.array([target - r])
        if _ekf_update(tr.kf, y, H, R):  # (not applied when S = u^T P u + R is exactly 0)
            tr.bounded_now = True

    # ---------------------------------------------------------------------------------- report
    def _reports(self, items: list[tuple[_Track, str]], fc: _FrameContext) -> list[TrackReport]:
        """One TrackReport per (track, status), in order; the arithmetic of all tracks at once.

        With a filter (state x = [p_W, v_W], P): r_W = p_W - o_W, range |r_W|, range sigma
        sqrt(u^T P_pp u + struct_sigma^2) with u = r_W / |r_W|, position_body_m = R_B_W r_W; for
        moving tracks the velocity when its largest sigma is small enough and it was measured; for
        a track whose filter velocity is assumed (static hypothesis, or the prior) the velocity
        evidence's when that rejects zero (``_evidence_now``) and is small enough; the time to
        closest approach t* = -r.w / |w|^2 (w = v_W - v_drone_W, v_W the reported velocity, else the
        filter's assumed one; none for a measured velocity too uncertain to report) when closing,
        and the distance at that closest approach with its sigma (``_miss_distances``: the
        covariance of the velocity used, the filter's P, the evidence's P_vv or none for the static
        hypothesis); with a reported velocity its speed's sigma (``_speed_sigma``, from the covariance of the
        velocity reported: the filter's P_vv or the evidence's). Without one: the first view's
        bearing turned into B (the camera offset is unknown without range) and the bounds.
        """
        s = self.settings
        out: list[TrackReport | None] = [None] * len(items)
        # a moving-hypothesis track that one camera alone has seen for longer than
        # moving_mono_max_s: its range is unobservable (a bearing does not range a moving
        # obstacle), so none is reported while its filter waits for the next stereo fix
        hold = s.moving_mono_max_s
        t_now = fc.t_s
        with_kf: list[int] = []
        without: list[int] = []
        for k, (tr, _st) in enumerate(items):
            stale = tr.kf is not None and tr.moving and t_now - tr.t_ranged > hold
            # a static state of two representative bearings (``_init_mono``) that no further bearing
            # has tested, or whose latest test failed (gated): its range is not reported. Two rays
            # meet somewhere whatever their errors: their one residual dof is the miss across their
            # epipolar plane, which says nothing of the range, so an error along the plane (a
            # bearing's jump, the obstacle's own motion in that plane) moves the point with no
            # residual; a third bearing from another place tests it (a static point fits all three)
            stale |= tr.kf is not None and not tr.moving and tr.pair_tested is False
            (with_kf if tr.kf is not None and not stale else without).append(k)
        R_B_W = fc.R_B_W
        if with_kf:
            trs = [items[k][0] for k in with_kf]
            X = np.array([tr.kf.x for tr in trs]).reshape(len(trs), 6)
            P6 = np.array([tr.kf.P for tr in trs]).reshape(len(trs), 6, 6)
            Ppp = np.ascontiguousarray(P6[:, :3, :3])  # (no slice per track)
            r_W = X[:, :3] - fc.o_W
            w = X[:, 3:] - fc.v_drone_W
            rng = np.sqrt(_dot_rows(r_W, r_W))
            u = r_W / np.maximum(rng, 1e-12)[:, None]
            p_B = r_W @ R_B_W.T
            b_B = p_B / np.maximum(rng, 1e-12)[:, None]
            var = np.maximum(_einsum("ki,kij,kj->k", u, Ppp, u), 0.0)
            gidx = self._gidx
            # a track that lists member features but whose range no feature fix measured this
            # frame (a carried state, the representative ray: a sliding centroid): at least
            # carried_range_floor_frac of it (tracks without member features: the filter's own)
            struct = np.array([max(tr.struct_sigma_m, s.carried_range_floor_frac * r)
                               if tr.id in gidx and tr.feature_range is None and tr.feature_stereo is None
                               and any(len(v.feature_ids) for v in tr.last_views)
                               else tr.struct_sigma_m
                               for tr, r in zip(trs, rng.tolist(), strict=True)])
            extra = self._member_spread(trs, rng, u, var + struct * struct)
            var_r = var + struct * struct + extra * extra
            # (a track reported lost is not scored: its bearing is not tested)
            hid = (self._occluded_by_members(trs, rng, u, var_r)
                   if any(items[k][1] != "lost" for k in with_kf) else np.zeros(len(trs)))
            var_r = var_r + hid * hid
            nb = self._stereo_neighbours(trs, rng, u, var_r)
            wn = self._window_neighbours(trs, rng, u, var_r)
            var_r = var_r + wn * wn
            var_r = var_r + self._own_stereo(trs, rng, var_r)
            sig = np.sqrt(var_r + nb * nb).tolist()
            rw = _dot_rows(r_W, w).tolist()
            ww = _dot_rows(w, w).tolist()
            moving = [j for j, tr in enumerate(trs) if tr.moving]
            vel_ok: dict[int, bool] = {}
            if moving:
                Pvv = np.array([trs[j].kf.P[3:, 3:] for j in moving])
                v_max = np.linalg.eigvalsh(Pvv).max(axis=1)
                v_sig = np.sqrt(np.maximum(v_max, 0.0)).tolist()
                vel_ok = {j: v_sig[m] <= s.velocity_report_max_sigma_mps and not trs[j].vel_assumed
                          for m, j in enumerate(moving)}
            # a track whose filter velocity is assumed or static (static features range it) but
            # whose shared features measured its velocity: that velocity evidence (P += q dt I
            # since its last measurement) when it rejects zero now (``vel_moving``, re-decided
            # with that grown P) and under the same sigma limit; otherwise a static-hypothesis
            # track's velocity is its filter's (the hypothesis its range and bounds rest on)
            ev = [j for j, tr in enumerate(trs) if tr.vel_acc is not None and not vel_ok.get(j, False)]
            v_ev: dict[int, tuple[np.ndarray, np.ndarray]] = {}  # (velocity, its covariance)
            if ev:
                Pe, mov = self._evidence_now([trs[j] for j in ev], t_now)
                e_max = np.linalg.eigvalsh(Pe).max(axis=1).tolist()
                for m_, (j, e, m) in enumerate(zip(ev, e_max, mov, strict=True)):
                    if m and math.sqrt(max(e, 0.0)) <= s.velocity_report_max_sigma_mps:
                        v_ev[j] = (trs[j].vel_acc[0].copy(), Pe[m_])
            rng_l = rng.tolist()
            kws: list[dict] = []
            # the reports with a time to closest approach: (j, t*, w (3,), the velocity's covariance
            # (3, 3) or None: the filter's own (with its position-velocity blocks), "static": none)
            closing: list[tuple[int, float, np.ndarray, np.ndarray | str | None]] = []
            for j, (k, tr) in enumerate(zip(with_kf, trs, strict=True)):
                kw = self._report_common(tr, items[k][1])
                kw["bearing_body"] = b_B[j]  # (item stores: the order kw.update(...) gave)
                kw["range_m"] = rng_l[j]
                kw["range_sigma_m"] = sig[j]
                kw["position_body_m"] = p_B[j]
                # one velocity per report: the reported one, else the velocity the filter assumes
                # (a static-hypothesis track's 0, an assumed velocity's prior: the hypothesis its
                # range rests on); a moving track whose measured velocity is too uncertain to
                # report has no time to closest approach either
                rwj, wwj = rw[j], ww[j]
                w_j, P_w = w[j], (None if tr.moving else "static")
                if j in v_ev:
                    v_W, P_v = v_ev[j]
                    w_j, P_w = v_W - fc.v_drone_W, P_v
                    rwj, wwj = float(_tdot(r_W[j], w_j)), float(_tdot(w_j, w_j))
                    kw.update(velocity_world_mps=v_W, speed_mps=math.sqrt(_tdot(v_W, v_W)),
                              speed_sigma_mps=_speed_sigma(v_W, P_v))
                elif vel_ok.get(j, False):
                    v_W = X[j, 3:].copy()  # (a moving track's: P_w is already None, the filter's P)
                    kw.update(velocity_world_mps=v_W, speed_mps=math.sqrt(_tdot(v_W, v_W)),
                              speed_sigma_mps=_speed_sigma(v_W, trs[j].kf.P[3:, 3:]))
                elif tr.moving and not tr.vel_assumed:
                    wwj = 0.0
                if rwj < 0 and wwj > 1e-12:
                    kw["ttc_s"] = -rwj / wwj
                    closing.append((j, kw["ttc_s"], w_j, P_w))
                srcs = tr.sources
                kw["source"] = _source_name("mono" in srcs, "stereo" in srcs, tr.bounded_now)
                kws.append(kw)
            if closing:
                J = [c[0] for c in closing]
                # the filter's own velocity: its P; the evidence's: its P_vv and no position-velocity
                # term; a static hypothesis's: the position's alone
                Pw = P6[J]
                own = [m_ for m_, c in enumerate(closing) if c[3] is not None]
                if own:
                    Pw[own, :3, 3:] = Pw[own, 3:, :3] = Pw[own, 3:, 3:] = 0.0
                    ev_ = [m_ for m_ in own if not isinstance(closing[m_][3], str)]
                    if ev_:
                        Pw[ev_, 3:, 3:] = np.array([closing[m_][3] for m_ in ev_])
                miss, miss_sig = _miss_distances(r_W[J], np.array([c[2] for c in closing]),
                                                 np.array([c[1] for c in closing]), Pw)
                for j, d_, sd in zip(J, miss.tolist(), miss_sig.tolist(), strict=True):
                    kws[j]["miss_distance_m"] = d_
                    kws[j]["miss_distance_sigma_m"] = sd
            for k, kw in zip(with_kf, kws, strict=True):
                out[k] = _new_full_report(kw)
        if without:
            trs = [items[k][0] for k in without]
            b_B = np.array([tr.last_views[0].b_W for tr in trs]) @ R_B_W.T
            b_B /= np.sqrt(_dot_rows(b_B, b_B))[:, None]
            for j, (k, tr) in enumerate(zip(without, trs, strict=True)):
                kw = self._report_common(tr, items[k][1])
                why = tr.reason or tr.bounds_reason
                if tr.kf is not None and tr.moving:
                    why = f"moving obstacle seen by one camera for > {hold:g} s (range unobservable)"
                elif tr.kf is not None:
                    why = ("mono triangulation not yet tested by a further bearing" if tr.gated_run == 0
                           else "its last bearing disagrees with its mono triangulation (gated)")
                kw.update(bearing_body=b_B[j], unobservable_reason=why,
                          source="bounds" if tr.bounds is not None else "")
                out[k] = _new_full_report(kw)
        return out  # type: ignore[return-value]

    def _member_spread(self, trs: list[_Track], rng: np.ndarray, u: np.ndarray,
                       var0: np.ndarray) -> np.ndarray:
        """The member-disagreement term of each report's range sigma (m), (K,) for the tracks trs
        with their reported ranges rng (K,) m, unit directions u (K, 3) in W from the body origin
        and their variances so far var0 (K,) m^2.

        The reported point is one member feature's point (or a filtered state); the truth along its
        bearing differs from it when that point is not the surface there (a corner on an occluding
        edge or sliding along one, a member of the background or of another object grouped into
        the track). The track's other members near it tell: with the member points of this frame
        (static tracks: the features' least-squares points that fit a static point; moving ones
        ranged by feature stereo: the shared features' two-ray points; a track whose velocity
        evidence rejects zero never uses static points: none without a feature stereo fix), the
        k = min(member_spread_min_n, n) whose directions from the body origin are nearest the
        reported one (ranges r_i, sigmas s_i in the reports' units: k sigma_r,f, scaled as a
        feature-ranged report's is, ``_posterior_sigma``; with the unscaled sigma_r,f the
        disagreement term switched on within the members' own noise) give a second estimate of
        the depth there, their
        median m, variance ~ (pi / 2) median(s_i^2) / k (a median of k normal values). Both
        estimate one depth when the members agree; when they disagree beyond that noise,
            d^2 = (m - r)^2 > var0 + (pi / 2) median(s_i^2) / k,
        one of them is not the surface along the bearing and the error is of order d, so
            extra = sqrt(w max(d^2 - var0 - (pi / 2) median(s_i^2) / k, 0))
        (w = member_spread_weight, 1: the sigma reaches the other estimate). 0 for tracks without
        member points this frame.
        """
        s = self.settings
        K = len(trs)
        out = np.zeros(K)
        if s.member_spread_weight <= 0 or not self._gidx:
            return out
        G = len(self._gidx)
        j_ls = np.full(G, -1, dtype=np.int64)
        j_st = np.full(G, -1, dtype=np.int64)
        for j, tr in enumerate(trs):
            gi = self._gidx.get(tr.id)
            if gi is None:
                continue
            if tr.moving and tr.feature_range is None and tr.feature_stereo is not None:
                j_st[gi] = j
            elif not tr.vel_moving:  # (a moving obstacle's static points are wrong)
                j_ls[gi] = j
        got = _report_members(((self._members_ls, j_ls), (self._members_st, j_st)))
        if got is None:
            return out
        jj, r, b, sr = got
        cos = _dot_rows(b, u.take(jj, 0))
        sel = _nearest_per_group(jj, cos, K, s.member_spread_min_n)
        js = jj[sel]
        k = np.bincount(js, minlength=K)
        med = _group_median(js, r[sel], K)
        s2 = _group_median(js, sr[sel] ** 2, K)
        d = np.abs(med - rng)
        ex2 = d * d - var0 - (0.5 * math.pi) * s2 / np.maximum(k, 1)
        return np.where(k > 0, np.sqrt(s.member_spread_weight * np.maximum(ex2, 0.0)), 0.0)

    def _stereo_neighbours(self, trs: list[_Track], rng: np.ndarray, u: np.ndarray,
                           var0: np.ndarray) -> np.ndarray:
        """The neighbour term of the range sigma (m), (K,) for the tracks trs with their reported
        ranges rng (K,) m, unit directions u (K, 3) in W from the body origin and their range
        variances so far var0 (K,) m^2; 0 except for a track ranged by its feature stereo fix
        alone this frame (no static-point fix).

        Such a report is one shared feature's two-ray point, filtered: its sigma is the two rays'
        noise (k sigma_r,f), which averages out over frames. A stereo match that sits on an
        occlusion boundary (a T-junction of the obstacle's outline and the background, a curved
        object's limb, which is a different line from each camera) is not one physical point:
        the two rays meet in front of or behind the surface, every frame alike, and the body's ray
        through that point grazes the obstacle, so the range along the reported bearing differs
        from the point's by more than the point's own error (tuned stereo_hover track 23: a point
        at 1.384 m, 5 cm in front of a 0.3 m sphere near its limb as cam0 sees it, beside it as
        cam1 sees it; the surface along the body's ray through it at 1.455 m; sigma 0.017 m).
        The track's other member points of this frame (``_member_spread``'s: shared features'
        two-ray points, and static least-squares points unless its velocity evidence rejects
        zero) sample the surface around the bearing: of those within the report's depth
        cluster, |r_i - r| <= feature_depth_gap_frac r (the split of ``_largest_depth_cluster``:
        a farther cluster is another surface, behind), within 60 deg of u (cos > 0.5) and not the
        reported point itself (within 1 mrad of u), the n = stereo_neighbour_n nearest in
        direction (fewer when fewer qualify), with ranges r_i and sigmas
        s_i (reports' units), give
            extra^2 = max_i ((r_i - r)^2 - s_i^2 - var0),   extra = sqrt(max(extra^2, 0))
        (the largest disagreement beyond the joint noise: next to a limb the other limb points
        agree with the reported one, the interior one does not; a median would follow the
        majority, as ``_member_spread``'s does).
        """
        s = self.settings
        K = len(trs)
        out = np.zeros(K)
        n_nb = int(s.stereo_neighbour_n)
        if n_nb <= 0 or not self._gidx or self._members_st is None:
            return out
        G = len(self._gidx)
        j_st = np.full(G, -1, dtype=np.int64)  # the stereo-ranged tracks' report index
        j_ls = np.full(G, -1, dtype=np.int64)
        for j, tr in enumerate(trs):
            if tr.feature_range is not None or tr.feature_stereo is None:
                continue
            gi = self._gidx.get(tr.id)
            if gi is None:
                continue
            j_st[gi] = j
            if not tr.vel_moving:  # (a moving obstacle's static points are wrong)
                j_ls[gi] = j
        if not (j_st >= 0).any():
            return out
        got = _report_members(((self._members_st, j_st), (self._members_ls, j_ls)))
        if got is None:
            return out
        jj, r, b, sr = got
        cos = _dot_rows(b, u.take(jj, 0))
        # in the depth cluster, within 60 deg of u, not the reported point itself (cos 1 mrad = 1 - 5e-7)
        keep = ((np.abs(r - rng[jj]) <= s.feature_depth_gap_frac * rng[jj]) & (cos > 0.5)
                & (cos < math.cos(1e-3)))
        if not keep.any():
            return out
        jj, r, sr, cos = jj[keep], r[keep], sr[keep], cos[keep]
        sel = _nearest_per_group(jj, cos, K, n_nb)
        js = jj[sel]
        d = r[sel] - rng[js]
        ex2 = np.full(K, -np.inf)
        np.maximum.at(ex2, js, d * d - sr[sel] ** 2 - var0[js])
        return np.sqrt(np.maximum(ex2, 0.0))

    def _window_neighbours(self, trs: list[_Track], rng: np.ndarray, u: np.ndarray,
                           var0: np.ndarray) -> np.ndarray:
        """The window term of the range sigma (m), (K,) for the tracks trs with their reported
        ranges rng (K,) m, unit directions u (K, 3) in W from the body origin and their range
        variances so far var0 (K,) m^2; 0 except for a track ranged by a member feature's static
        point this frame (``feature_point``), on any rig.

        The front end tracks a feature by the image window around it (KLT, ``window_px`` wide, as
        an angle rho = window_px / 2 / f with f the camera's tracked px per rad; one rho for every
        report, the widest over the rig's cameras).
        When that window holds a surface at another depth (the feature sits near an occluding edge:
        a T-junction of a near outline and a farther surface, a curved obstacle's limb, a point
        that a nearer obstacle is passing), the window's motion is a blend of two parallaxes, and
        on a mono rig a blend, or a slide along the flight's epipolar plane, fits a static point at
        a wrong depth as well as a real point fits its own: the feature's residual does not tell
        (renderer truth, 7 mono scenes: chi's median 3.8 for the reports with z^2 > 25, 0.7 for
        features whose rays hit one fixed point, p90 3.2). The other static member points of this
        frame (every track's, ``_members_ls``: the surfaces around, whatever track grouped them)
        inside the window angle of the reported direction, not the reported point itself (within
        1 mrad), ranges r_i and sigmas s_i (reports' units), tell that a second depth is there:
            extra^2 = max_i ((r_i - r)^2 - s_i^2 - var0),   extra = sqrt(max(extra^2, 0))
        (the largest disagreement beyond the joint noise, as ``_stereo_neighbours``: the range along
        the reported bearing may be either surface's). On a stereo rig too: each camera's window
        holds its own blend, and the static point over both cameras' rays of 0.5 s is no check of
        it (the demo's moving box, track 70, and a static point 1.5 m beyond its obstacle, track 46:
        see ObstacleFusion's window_px)."""
        K = len(trs)
        out = np.zeros(K)
        rho = self._window_rad
        mem = self._members_ls
        if rho <= 0 or mem is None or not len(mem[0]):
            return out
        js = [j for j, tr in enumerate(trs) if tr.feature_point is not None and tr.id in self._gidx]
        if not js:
            return out
        _g, r, b, sr = mem
        ja = np.array(js)
        cos = u.take(ja, 0) @ b.T  # (J, M): every report against every member point
        inside = (cos > math.cos(rho)) & (cos < math.cos(1e-3))
        d2 = (r[None, :] - rng[ja][:, None]) ** 2 - (sr * sr)[None, :] - var0[ja][:, None]
        ex2 = np.where(inside, d2, -np.inf).max(axis=1)
        out[ja] = np.sqrt(np.maximum(ex2, 0.0))
        return out

    def _own_stereo(self, trs: list[_Track], rng: np.ndarray, var0: np.ndarray) -> np.ndarray:
        """The own-stereo term of the range variance (m^2), (K,) for the tracks trs with their
        reported ranges rng (K,) m and range variances so far var0 (K,) m^2; 0 except for a track
        ranged by a member feature's static point (``feature_point``) whose feature has a two-ray
        point this frame (``_feature_stereo``: same track, same id).

        The static point is the least-squares point of the feature's rays over feature_memory_s
        from both cameras; it holds only if the point did not move. An obstacle approaching along
        the flight line turns each feature's bearing as a static point at a nearer depth would,
        so its rays fit a static point (the chi test passes) in front of it (the demo's moving box,
        track 70 at 1.23-1.57 s: static points 3.6-4.8 m, the box at 4.9-6.3 m, sigma 0.19-0.55 m).
        The feature's two-ray point of this instant, r_st with sigma s_st (k sigma_r,f, reports'
        units), is the same physical point without that assumption, so beyond their joint noise
        their disagreement is the static point's model error, of either sign:
            extra^2 = max((r_st - r)^2 - s_st^2 - var0, 0)
        (as ``_member_spread`` and ``_stereo_neighbours``, the sigma reaches the other estimate; a
        static point that agrees with its own two-ray point is left as it is).
        """
        K = len(trs)
        out = np.zeros(K)
        if not self.settings.static_own_stereo or self._stereo_pairs is None or not self._gidx:
            return out
        gidx = self._gidx
        q = [(j, gidx[tr.id], tr.feature_point_fid) for j, tr in enumerate(trs)
             if tr.feature_range is not None and tr.feature_point_fid is not None and tr.id in gidx]
        if not q:
            return out
        gs, fid_s, r_s, s_s = self._stereo_pairs
        qj, qg, qf = (np.array(c, dtype=np.int64) for c in zip(*q, strict=True))
        # one key per (track index, feature id); the two-ray points' keys are unique
        # (``_feature_stereo``'s intersection keeps first occurrences)
        lo = min(int(fid_s.min()), int(qf.min()))
        span = max(int(fid_s.max()), int(qf.max())) - lo + 1
        k_s = gs * span + (fid_s - lo)
        k_q = qg * span + (qf - lo)
        order = k_s.argsort(kind="stable")
        at = order[np.minimum(k_s[order].searchsorted(k_q), len(k_s) - 1)]
        hit = k_s[at] == k_q
        if not hit.any():
            return out
        qj, i = qj[hit], at[hit]
        d = r_s[i] - rng[qj]
        out[qj] = np.maximum(d * d - s_s[i] ** 2 - var0[qj], 0.0)
        return out

    def _occluded_by_members(self, trs: list[_Track], rng: np.ndarray, u: np.ndarray,
                             var0: np.ndarray) -> np.ndarray:
        """The occlusion term of each report's range sigma (m), (K,) for the tracks trs with their
        reported ranges rng (K,) m, unit directions u (K, 3) in W from the body origin and their
        range variances so far var0 (K,) m^2.

        A report's range is the range along its bearing from the body origin. The cameras sit off
        the body origin (a stereo rig's by half the baseline), so a point one camera sees past the
        edge of a nearer obstacle can be hidden from the body origin by it (heldout_stereo_flying:
        ground points at 3.3-5 m seen from cam0 past a box 0.8-2 m away, the body's ray toward
        them on the box); a feature whose rays stayed on its point while a nearer obstacle moved in
        front of it is hidden from the camera too. The other tracks' member points of this frame
        (``_member_spread``'s: static least-squares points, shared features' two-ray points; range
        r_i, direction b_i from the body origin, sigma s_i in the reports' units) tell: when the
        report's direction u lies inside the angular convex hull of n >= occluder_min_members
        points of one other track that are nearer than it beyond the joint noise,
            r_i < r - 3 sqrt(var0 + s_i^2),
        that track's surface spans the bearing in front of the reported point, and the range along
        the bearing is that surface's: the term is r - median(r_i) (the report stays: its point is
        real, but its bearing is not clear up to its range). The hull is widened by the tracked
        window's angle rho (``_window_neighbours``' one angle: the largest window_px / 2 over the px per
        rad of the tracked images): the nearer surface spans at least its points' hull, and when it comes
        within rho of u it reaches into the window the front end tracks the reported point by, so
        that point may be a corner the surface is passing over (its window a blend of two depths, the window
        term's model) or already behind it (val_turning, with the mono outline rule: track 73's
        point at 17.7 m, its ray on a nearer box at 7.4-8.1 m, 1.0-1.6 deg outside the hull of
        the box's track's points, none of them within rho: z^2 70-2039). The hull test: the points
        projected on the plane tangent at u (gnomonic, p_i = (b_i.e1, b_i.e2) / b_i.u, straight
        lines stay straight), each replaced by the 8 vertices of a regular octagon of circumradius
        tan(rho) about it (the hull widened by 0.92 rho to rho), enclose the origin when no
        half-plane through it holds them all, i.e. when the largest gap between their sorted polar
        angles is below pi. 0 without such a track.
        """
        s = self.settings
        K = len(trs)
        out = np.zeros(K)
        n_min = int(s.occluder_min_members)
        if n_min <= 0 or not self._gidx:
            return out
        parts = [m for m in (self._members_ls, self._members_st) if m is not None and len(m[0])]
        if not parts:
            return out
        if len(parts) == 1:
            g, r, b, sr = parts[0]
        else:
            g = np.concatenate([m[0] for m in parts])
            r = np.concatenate([m[1] for m in parts])
            b = np.concatenate([m[2] for m in parts])
            sr = np.concatenate([m[3] for m in parts])
        gidx = self._gidx
        own = np.array([gidx.get(tr.id, -1) for tr in trs], dtype=np.int64)
        off = self._cam_offset_m
        # pre-selection by track (K x tracks, not K x points): each track's points' mean direction
        # c_g, angular radius rho_g about it and nearest range; a pair (report j, track g) can
        # hold a point inside the hull or within the offset of u_j only when angle(u_j, c_g) <=
        # rho_g + asin(offset / min r), and a nearer point beyond the noise (below) only when
        # min r < r_j - 3 sqrt(var0_j) (<= r_j - 3 sqrt(var0_j + s_i^2) for every point i)
        if len(g) > 1 and (g[1:] < g[:-1]).any():  # (each part is sorted by track already)
            order = g.argsort(kind="stable")
            g, r, b, sr = g[order], r[order], b[order], sr[order]
        # each track's run of rows in the sorted g (np.unique's, cheaper) and its length
        gstart = np.concatenate(([0], (g[1:] != g[:-1]).nonzero()[0] + 1))
        gcnt = np.concatenate((gstart[1:], [len(g)])) - gstart
        ug = g[gstart]
        cg = np.add.reduceat(b, gstart, axis=0)
        cg /= np.maximum(np.sqrt(_dot_rows(cg, cg)), 1e-12)[:, None]
        cos_b = _dot_rows(b, cg.repeat(gcnt, axis=0)).clip(-1.0, 1.0)
        cos_min = np.minimum.reduceat(cos_b, gstart)
        rmin = np.minimum.reduceat(r, gstart)
        rho = self._window_rad  # (the hull test's margin: the chosen point's tracked window)
        reach = np.arccos(cos_min) + np.arcsin(np.minimum(off / np.maximum(rmin, 1e-9), 1.0)) + rho
        near = rng - 3.0 * np.sqrt(var0)
        pair = ((u @ cg.T) >= np.cos(np.minimum(reach, math.pi))[None, :]) & (rmin[None, :] < near[:, None])
        pair &= ug[None, :] != own[:, None]
        pj, pg = np.nonzero(pair)
        if not len(pj):
            return out
        # candidate (report, point) pairs: the pre-selected tracks' points, nearer than the report
        # beyond the noise, in the hemisphere ahead of the bearing
        n_p = gcnt[pg]
        jj = pj.repeat(n_p)
        mm = (gstart[pg] - (n_p.cumsum() - n_p)).repeat(n_p) + np.arange(int(n_p.sum()))
        cos_jm = _dot_rows(u.take(jj, 0), b.take(mm, 0))
        keep = (r[mm] < rng[jj] - 3.0 * np.sqrt(var0[jj] + sr[mm] ** 2)) & (cos_jm > 0.5)
        if not keep.any():
            return out
        jj, mm, cos_jm = jj[keep], mm[keep], cos_jm[keep]
        key = jj * (int(g.max()) + 1) + g[mm]  # (non-decreasing: pairs in (report, track) order)
        first_q = np.empty(len(key), dtype=bool)  # np.unique(key, return_inverse, return_counts)
        first_q[0] = True
        np.not_equal(key[1:], key[:-1], out=first_q[1:])
        inv = first_q.cumsum() - 1
        q0 = first_q.nonzero()[0]
        ukey, cnt = key[q0], np.concatenate((q0[1:], [len(key)])) - q0
        n_q = len(ukey)
        q_rep = ukey // (int(g.max()) + 1)  # each (report, track) pair's report
        # (a) the hull test, all pairs at once: the polar angle of each point about u_j in the
        # plane tangent at u_j, sorted within each pair; the gaps between neighbours and the wrap
        e = np.zeros_like(u)
        e[np.arange(K), np.argmin(np.abs(u), axis=1)] = 1.0
        e1 = _cross(u, e)
        e1 /= np.sqrt(_dot_rows(e1, e1))[:, None]
        e2 = _cross(u, e1)
        B = b.take(mm, 0)
        x1, x2 = _dot_rows(B, e1.take(jj, 0)), _dot_rows(B, e2.take(jj, 0))
        ang = np.arctan2(x2, x1)  # (gnomonic: same angle)
        enclosed = (cnt >= n_min) & _polar_enclosed(ang, inv, n_q)
        if rho > 0:
            # ... of the hull widened by the window's angle, for the pairs it may change: each
            # point's gnomonic position p_i = (x1, x2) / cos replaced by the 8 vertices of a
            # regular octagon of circumradius tan(rho) about it. A pair whose hull lies farther
            # than tan(rho) from the origin cannot change; for any unit n, min_i (-p_i.n) bounds
            # that distance from below (n: opposite the points' mean direction), so only pairs
            # with the bound <= tan(rho) are widened (the same answers as widening every pair)
            t = math.tan(rho)
            g1, g2 = x1 / cos_jm, x2 / cos_jm
            nr = np.maximum(np.sqrt(g1 * g1 + g2 * g2), 1e-12)
            s1 = np.bincount(inv, weights=g1 / nr, minlength=n_q)
            s2 = np.bincount(inv, weights=g2 / nr, minlength=n_q)
            sn = np.sqrt(s1 * s1 + s2 * s2)
            n1 = np.where(sn > 0, -s1 / np.maximum(sn, 1e-300), 1.0)
            n2 = np.where(sn > 0, -s2 / np.maximum(sn, 1e-300), 0.0)
            lb = np.full(n_q, np.inf)
            np.minimum.at(lb, inv, -(g1 * n1[inv] + g2 * n2[inv]))
            cand = ~enclosed & (cnt >= n_min) & (lb <= t)
            if cand.any():
                m = cand[inv]
                q = np.arange(8) * (math.pi / 4.0)
                y1 = (g1[m][:, None] + t * np.cos(q)[None, :]).ravel()
                y2 = (g2[m][:, None] + t * np.sin(q)[None, :]).ravel()
                enclosed |= cand & _polar_enclosed(np.arctan2(y2, y1), inv[m].repeat(8), n_q)
        sel_a = enclosed[inv]
        # (b) within the cameras' offset of the bearing: the points whose distance from the
        # bearing's line, r_i sin(angle), is at most the largest camera offset from the body origin
        # (the body's and a camera's rays toward the reported point are at most that far apart
        # there, so the surface around those points can cut the one and not the other); two or more
        sel_b = np.zeros(len(mm), dtype=bool)
        if off > 0:
            c_ = cos_jm
            close = r[mm] * np.sqrt(np.maximum(1.0 - c_ * c_, 0.0)) <= off
            n_close = np.bincount(inv[close], minlength=n_q)
            sel_b = close & (n_close >= 2)[inv]
        for sel in (sel_a, sel_b):
            if not sel.any():
                continue
            med = _group_median(inv[sel], r[mm[sel]], n_q)
            hq = (np.bincount(inv[sel], minlength=n_q) > 0).nonzero()[0]
            np.maximum.at(out, q_rep[hq], rng[q_rep[hq]] - med[hq])
        return out

    @staticmethod
    def _report_common(tr: _Track, status: str) -> dict:
        """A report's fields that do not depend on its range, over every field's default (the
        dict ``_new_full_report`` takes)."""
        b = tr.bounds
        return {
            **_REPORT_DEFAULTS,
            "id": tr.id,
            "status": status,
            "camera": tr.cameras[0] if len(tr.cameras) == 1 else list(tr.cameras),
            "range_min_m": None if b is None else b.range_min_m,
            "range_max_m": None if b is None else b.range_max_m,
            "label": tr.label,
            "gated": tr.gated,
            "nis": tr.nis,
            "innovation": tr.innovation,
            "attributes": tr.attributes,
        }


def _report_maker():
    """A TrackReport constructor for the hot path. TrackReport is a frozen dataclass whose __init__
    sets its 21 fields one by one through object.__setattr__ (~4x the cost of the rest of a report);
    when it has no __post_init__ (nothing to validate) and keeps its fields in __dict__, the report
    is built by filling __dict__ with the defaults and the given fields (the same object as
    TrackReport(**kw); tests compare them). Otherwise the constructor itself is used.

    Returns (make_full(d), defaults): make_full takes a dict that already holds every field
    (``defaults``, the fields with a plain default, updated with the others: what ``_report_common``
    starts from)."""
    import dataclasses

    flds = dataclasses.fields(TrackReport)
    defaults = {f.name: f.default for f in flds if f.default is not dataclasses.MISSING}
    if (hasattr(TrackReport, "__post_init__") or hasattr(TrackReport, "__slots__")
            or any(f.default is dataclasses.MISSING and f.default_factory is not dataclasses.MISSING
                   and f.name != "attributes" for f in flds)):
        return (lambda d: TrackReport(**d)), defaults
    new = object.__new__

    def make_full(d: dict) -> TrackReport:
        rep = new(TrackReport)
        rep.__dict__.update(d)
        return rep

    return make_full, defaults


_new_full_report, _REPORT_DEFAULTS = _report_maker()

_SOURCE_NAMES = {
    (m, st, b): "+".join(x for x, on in (("mono", m), ("stereo", st), ("bounds", b)) if on)
    for m in (False, True) for st in (False, True) for b in (False, True)
}


def _source_name(mono: bool, stereo: bool, bounds: bool) -> str:
    """A report's ``source``: the sources that fed it joined by "+", in the order mono, stereo,
    bounds (CONVENTIONS.md)."""
    return _SOURCE_NAMES[(mono, stereo, bounds)]



def _ekf_predict(kf: ExtendedKalmanFilter) -> None:
    """``kf.predict()`` (filterpy's ExtendedKalmanFilter, no control input) with the same operations
    in the same order, without its bookkeeping copies (x_prior, P_prior: nothing here reads them):
        x = F x,   P = F P F^T + Q."""
    F = kf.F
    kf.x = F @ kf.x
    kf.P = (F @ kf.P) @ F.T + kf.Q


def _inv_small(S: np.ndarray) -> np.ndarray | None:
    """Inverse (k, k) of an innovation covariance S (k, k), k = 1, 2 or 3, by cofactors in Python
    floats: S^-1 = adj(S) / det(S); None when det(S) is exactly 0 (singular: the caller rejects the
    measurement). (filterpy's update inverts with scipy's LAPACK inv, ~15 us a call, and raises on a
    singular S; these agree to rounding, |difference| ~1e-16 relative for the well-conditioned
    S = H P H^T + R here: tests/estimators/test_ekf_filterpy_agreement.py.)"""
    k = len(S)
    if k == 2:
        (a, b), (c, d) = S.tolist()
        det = a * d - b * c
        if det == 0.0:
            return None
        return np.array(((d / det, -b / det), (-c / det, a / det)))
    if k == 1:
        s00 = float(S[0, 0])
        return None if s00 == 0.0 else np.array(((1.0 / s00,),))
    (a, b, c), (d, e, f), (g, h, i) = S.tolist()
    A, B, C = e * i - f * h, f * g - d * i, d * h - e * g
    det = a * A + b * B + c * C
    if det == 0.0:
        return None
    return np.array(((A / det, (c * h - b * i) / det, (b * f - c * e) / det),
                     (B / det, (a * i - c * g) / det, (c * d - a * f) / det),
                     (C / det, (b * g - a * h) / det, (a * e - b * d) / det)))


def _ekf_update(kf: ExtendedKalmanFilter, y: np.ndarray, H: np.ndarray, R: np.ndarray) -> bool:
    """``kf.update(y, HJacobian=lambda x: H, Hx=lambda x: 0, R=R)`` (filterpy's
    ExtendedKalmanFilter: residual y = z - h(x) already formed, (k,), k <= 3; H (k, 6); R (k, k)):
    filterpy's operations in its order, without its bookkeeping (deep copy of z, x_post, P_post,
    likelihood resets: nothing here reads them) and with S inverted by cofactors (``_inv_small``;
    equal to filterpy's to rounding, tests/estimators/test_ekf_filterpy_agreement.py). Sets S, SI,
    K, y (the array passed: callers pass a fresh one), and the Joseph-form update
        S = H P H^T + R,   K = P H^T S^-1,
        x = x + K y,   P = (I - K H) P (I - K H)^T + K R K^T.
    Returns True, or False (the filter untouched) when S is exactly singular (no inverse: filterpy
    raised there; degenerate settings such as a zero bearing sigma on a zero-variance state)."""
    P = kf.P
    c = _SLICE_POS if H is _H_POS else _SLICE_VEL if H is _H_VEL else None
    if c is not None:  # H = [I 0] / [0 I]: P H^T and H P H^T are P's columns and block
        # (the same values: every product but one per entry is an exact 0)
        PHT = P[:, c]
        S = PHT[c] + R
    else:
        PHT = P @ H.T
        S = H @ PHT + R
    SI = _inv_small(S)
    if SI is None:
        return False
    kf.S = S
    kf.SI = SI
    kf.K = K = PHT @ SI
    kf.y = y
    kf.x = kf.x + K @ y
    if c is not None:  # K H = [K 0] / [0 K]
        I_KH = _EYE6.copy()
        I_KH[:, c] -= K
    else:
        I_KH = _EYE6 - K @ H
    kf.P = (I_KH @ P) @ I_KH.T + (K @ R) @ K.T
    return True


def _posterior_sigma(sig_r: np.ndarray, chi: np.ndarray, n: np.ndarray, nu0: float) -> np.ndarray:
    """First-order range sigmas sig_r (K,) m of features' least-squares points (at the nominal ray
    noise sigma_f), scaled by the square root of each feature's estimated noise variance factor:
    chi (K,) is each feature's mean squared ray miss over 2 sigma_f^2 d^2 (``_features_batch``),
    from n (K,) rays (forgetting weights summed); the fitted point took 3 of the 2n residual dof,
    so its own fit's a-posteriori variance factor is chi 2n / (2n - 3) (E = 1 at the nominal
    noise). With a prior of nu0 dof at the nominal noise (factor 1), the conjugate (scaled
    inverse chi-square) estimate pools the two:
        s2 = (nu0 + 2n chi) / (nu0 + 2n - 3)      (denominator floored at 1)
    (nu0 = 0: the fit's own factor; a young feature's few rays lean on the prior). Returns
    sig_r sqrt(s2): a feature whose rays agree better than sigma_f is surer than the nominal one,
    one whose rays miss more (a corner sliding along an edge, a T-junction) less sure."""
    n2 = 2.0 * np.asarray(n, dtype=float)
    s2 = (nu0 + np.maximum(chi, 0.0) * n2) / np.maximum(nu0 + n2 - 3.0, 1.0)
    return sig_r * np.sqrt(s2)


def _miss_distances(r: np.ndarray, w: np.ndarray, t: np.ndarray,
                    P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance at closest approach and its 1-sigma for K reports at once: r (K, 3) m the obstacle
    from the body origin, w (K, 3) m/s its velocity relative to the body (|w| > 0), t (K,) s the time
    of closest approach t* = -r.w / |w|^2 (the value reported as ``ttc_s``), P (K, 6, 6) the
    covariance of (position, velocity) (drone's velocity exact).

    The miss vector m = r + t* w is r's component across w, d = |m|. t* is stationary in d, so to
    first order dd = n^T (dr + t* dw), n = m / d: the Jacobian J = [n^T, t* n^T] and the variance
    J P J^T = n^T C n, C = P_pp + t* (P_pv + P_vp) + t*^2 P_vv the covariance of the position
    extrapolated to t*. Across both w and n (e = w / |w| x n) d changes only to second order,
    sqrt(d^2 + de^2) - d, which is the whole error near a head-on approach: the variance adds
    s_e^2 / (d^2 + s_e), s_e = e^T C e. Far from head-on that is s_e^2 / d^2 (the mean square of
    the second-order error is 3 s_e^2 / 4 d^2): negligible; at d = 0 it makes the variance the
    trace of C across w, the mean square of |m| there, whatever direction n is taken. In between
    the sigma is the root mean square of (true - reported distance) for m Gaussian across w, or up
    to 31 % more, never less (d / sqrt(n^T C n) from 0 to 100, s_e / n^T C n from 0.0025 to 900;
    the first order alone is down to a third of it where s_e >> n^T C n).
    Returns (d (K,) m, sigma (K,) m)."""
    m = r + t[:, None] * w
    d = np.sqrt(_dot_rows(m, m))
    u = w / np.sqrt(_dot_rows(w, w))[:, None]
    head_on = d <= 1e-9  # (m: rounding noise of r's size, its direction meaningless)
    n = m / np.where(head_on, 1.0, d)[:, None]
    if head_on.any():  # no direction of the miss: any one across w
        n[head_on] = _tangent_basis(u[head_on])[:, :, 0]
    G = np.empty((len(d), 2, 6))  # the Jacobians [n, t* n] of d and [e, t* e] across
    G[:, 0, :3] = n
    G[:, 1, :3] = _cross(u, n)
    G[:, :, 3:] = G[:, :, :3] * t[:, None, None]
    s = _einsum("kai,kij,kaj->ka", G, P, G)  # (J P J^T = n^T C n)
    s_e = np.maximum(s[:, 1], 0.0)
    var = s[:, 0] + s_e * s_e / np.maximum(d * d + s_e, 1e-300)
    return d, np.sqrt(np.maximum(var, 0.0))


def _speed_sigma(v_W: np.ndarray, P_vv: np.ndarray) -> float:
    """1-sigma (m/s) of the speed |v| of a velocity v_W (3,) m/s with covariance P_vv (3, 3), to
    first order: d|v| = u^T dv with u = v / |v|, so sigma_s = sqrt(u^T P_vv u); at |v| ~ 0 (no
    direction) the largest axis sigma, sqrt(lambda_max(P_vv))."""
    n = math.sqrt(_tdot(v_W, v_W))
    if n < 1e-9:
        return math.sqrt(max(float(np.linalg.eigvalsh(P_vv)[-1]), 0.0))
    u = v_W / n
    return math.sqrt(max(float(u @ P_vv @ u), 0.0))


def _rotate_rows(X: np.ndarray, cam: np.ndarray, R_W_C) -> np.ndarray:
    """Rows of X (N, 3), each in its camera's frame ``cam`` (N,) index into R_W_C, rotated to W."""
    if len(R_W_C) == 1:
        return X @ R_W_C[0].T
    for k, R in enumerate(R_W_C):
        m = cam == k
        if m.any():
            X[m] = X[m] @ R.T
    return X

def _ray_covariance(d: np.ndarray, sigma_along_m: float, sigma_rad: float) -> np.ndarray:
    """Covariance (3, 3) of a point at offset d (3,) from a sensor: sigma_along_m along d and
    |d| * sigma_rad across it:  R = s_r^2 u u^T + (|d| s_b)^2 (I - u u^T)."""
    dx, dy, dz = d.tolist()  # (in Python floats: ~4x faster than numpy on one 3x3)
    n = math.sqrt(dx * dx + dy * dy + dz * dz)
    m = max(n, 1e-12)
    u = (dx / m, dy / m, dz / m)
    a = sigma_along_m**2
    t = max(n * sigma_rad, 1e-6) ** 2
    return np.array([[a * (u[i] * u[j]) + t * ((1.0 if i == j else 0.0) - u[i] * u[j])
                      + (1e-12 if i == j else 0.0) for j in range(3)] for i in range(3)])


def _ray_covariances(d: np.ndarray, sigma_along_m: np.ndarray, sigma_rad: np.ndarray) -> np.ndarray:
    """``_ray_covariance`` of K points at once: d (K, 3) m, sigma_along_m (K,) m, sigma_rad (K,)
    -> (K, 3, 3)."""
    n = np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2])
    u = d / np.maximum(n, 1e-12)[:, None]
    uu = u[:, :, None] * u[:, None, :]
    s_t = np.maximum(n * sigma_rad, 1e-6)
    eye = np.eye(3)
    return ((sigma_along_m**2)[:, None, None] * uu + (s_t**2)[:, None, None] * (eye - uu)
            + eye * 1e-12)


def _adjugate_det3(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Adjugate (K, 3, 3) and determinant (K,) of K 3x3 matrices A (K, 3, 3), by cofactors
    (A^-1 = adj(A) / det(A); LAPACK's batched inv / det cost ~10x more on 3x3 matrices)."""
    a, b, c = A[:, 0, 0], A[:, 0, 1], A[:, 0, 2]
    d, e, f = A[:, 1, 0], A[:, 1, 1], A[:, 1, 2]
    g, h, i = A[:, 2, 0], A[:, 2, 1], A[:, 2, 2]
    adj = np.empty_like(A)
    adj[:, 0, 0] = e * i - f * h
    adj[:, 0, 1] = c * h - b * i
    adj[:, 0, 2] = b * f - c * e
    adj[:, 1, 0] = f * g - d * i
    adj[:, 1, 1] = a * i - c * g
    adj[:, 1, 2] = c * d - a * f
    adj[:, 2, 0] = d * h - e * g
    adj[:, 2, 1] = b * g - a * h
    adj[:, 2, 2] = a * e - b * d
    det = a * adj[:, 0, 0] + b * adj[:, 1, 0] + c * adj[:, 2, 0]
    return adj, det


def _tcross(a, b) -> tuple[float, float, float]:
    """a x b for two 3-tuples of floats."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _tdot(a, b) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _rotate_about_batch(b: np.ndarray, n: np.ndarray, ca: np.ndarray, sa: np.ndarray) -> np.ndarray:
    """Rodrigues rotation of the rows of b (K, 3) about the unit axes n (K, 3) by the angles whose
    cosines / sines are ca, sa (K,):  b cos + (n x b) sin + n (n.b)(1 - cos)."""
    nxb = _cross(n, b)
    k = _dot_rows(n, b) * (1.0 - ca)
    return b * ca[:, None] + nxb * sa[:, None] + n * k[:, None]


def _dot_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise a . b of (K, 3) arrays -> (K,)."""
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


def _noisy_bound_rays_batch(c_a, b_a, c_b, b_b, delta):
    """The ray pairs whose bounds ``_bounds_batch`` unites (module docstring), for K ray pairs at
    once: c_a, b_a, c_b, b_b (K, 3) in W (m, unit directions), delta (K,) rad.

    Returns (owner (N,), c_a, b_a', c_b, b_b' (N, 3)): the ray pairs whose bounds are united, each
    with the index of its input pair: ray a projected into the epipolar plane of (baseline, ray b)
    (normal n = (c_b - c_a) x b_b, or b_a x b_b at zero baseline) with ray b turned in it by 0 and
    +-delta, and ray a turned in it by +-delta (about c_a) with ray b, plus ray a itself when ray b
    is within delta of it; just the two rays when there is no plane, delta is 0 or ray a lies along
    the normal.
    """
    n = _cross(c_b - c_a, b_b)  # epipolar plane normal
    nn = np.sqrt(_dot_rows(n, n))
    zero_base = nn < 1e-9
    if zero_base.any():  # zero baseline: the plane of the two bearings
        n[zero_base] = _cross(b_a[zero_base], b_b[zero_base])
        nn = np.sqrt(_dot_rows(n, n))
    plane = (delta > 0) & (nn >= 1e-12)
    n = n / np.where(plane, nn, 1.0)[:, None]
    an = _dot_rows(b_a, n)
    b_in = b_a - an[:, None] * n
    na = np.sqrt(_dot_rows(b_in, b_in))
    plane &= na >= 1e-9  # ray a along the normal: nothing to project
    b_in = b_in / np.where(plane, na, 1.0)[:, None]
    to_a = np.arctan2(_dot_rows(n, _cross(b_b, b_in)), _dot_rows(b_b, b_in))  # signed, about n
    ca, sa = np.cos(delta), np.sin(delta)
    p = plane.nonzero()[0]
    q = (~plane).nonzero()[0]
    par = p[np.abs(to_a[p]) <= delta[p]]  # (exactly parallel: a rotation would leave a rounding-size angle)
    np_, bp = n.take(p, 0), b_b.take(p, 0)
    owner = np.concatenate([q, p, p, p, p, p, par])
    c_a_o = c_a.take(owner, 0)
    c_b_o = c_b.take(owner, 0)
    b_in_p = b_in.take(p, 0)
    cp, sp = ca[p], sa[p]
    b_a_o = np.concatenate([b_a.take(q, 0), b_in_p, b_in_p, b_in_p, _rotate_about_batch(b_in_p, np_, cp, sp),
                            _rotate_about_batch(b_in_p, np_, cp, -sp), b_in.take(par, 0)])
    b_b_o = np.concatenate([b_b.take(q, 0), bp, _rotate_about_batch(bp, np_, cp, sp),
                            _rotate_about_batch(bp, np_, cp, -sp), bp, bp, b_in.take(par, 0)])
    return owner, c_a_o, b_a_o, c_b_o, b_b_o
