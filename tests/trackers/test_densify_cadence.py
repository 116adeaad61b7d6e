"""Densify's cadence is a duration (``FrontEnd`` ``densify_s``, default 2/30 s), applied as a frame
count at the frame rate seen: every 2nd frame at 30 fps (the ``densify_every`` 2 it was fitted as,
so 30-fps outputs are unchanged), every 7th at 100 fps (2/30 s x 100 = 6.67, rounded), where every
2nd frame ran densify 3.3x as often a second as at 30 fps. Truth: the counts by hand from the frame
times the test gives, and one small textured disc as the only texture (one small track)."""

from __future__ import annotations

import numpy as np
import pytest

from estimators.errors import ConfigError
from estimators.rig import mono_forward_rig
from tests.trackers.conftest import Patch, SphereScene, equidistant
from trackers.frontend import FrontEnd


def densify_frames(fps: float, n: int, stride: int = 1, **options) -> list[int]:
    """Frames at which the front end asked densify for the one small track of a textured 10-deg disc
    ahead of a 320 x 240 lens on a blank environment, over n frames processed of a camera at fps:
    every ``stride``-th of its frames (frame index k, t_s k / fps)."""
    model = equidistant()
    scene = SphereScene(model, blank_env=True)
    fe = FrontEnd(mono_forward_rig(model), **options)
    ft = fe.trackers["cam0"]
    asked: list[int] = []
    densify = ft.densify

    def spy(image, centres_uv, radii_px, frame, t_s, *a, **k):
        asked.extend([frame] * len(centres_uv))
        return densify(image, centres_uv, radii_px, frame, t_s, *a, **k)

    ft.densify = spy
    disc = Patch(np.array([0.2, 0.0, 1.0]) / np.hypot(0.2, 1.0), np.radians(10.0), seed=3)
    for k in range(0, n * stride, stride):
        fe.process({"cam0": scene.render(None, [disc])}, k, k / fps)
    return asked


@pytest.mark.parametrize("fps, every", [(30.0, 2), (100.0, 7), (60.0, 4)])
def test_densify_runs_every_densify_s_as_frames_at_the_rate_seen(fps, every):
    """The one small track is densified every 2/30 s as frames: 2 at 30 fps (as densify_every 2
    was), 4 at 60, 7 at 100 (at the base, every 2nd frame at every rate: fails at 100 and 60 fps)."""
    asked = densify_frames(fps, 60)
    assert len(asked) >= 3, asked
    gaps = np.diff(asked)
    assert gaps.min() == every, (asked, every)


def test_densify_s_zero_is_every_frame_and_the_old_key_names_its_replacement():
    asked = densify_frames(100.0, 30, densify_s=0.0)
    assert len(asked) >= 3 and np.diff(asked).min() == 1, asked
    with pytest.raises(ConfigError, match=r"densify_every.*densify_s"):
        FrontEnd(mono_forward_rig(equidistant()), densify_every=2)
    with pytest.raises(ConfigError, match="densify_s"):
        FrontEnd(mono_forward_rig(equidistant()), densify_s=-1.0)



def test_densify_waits_in_frames_processed_when_the_caller_skips_frame_indices():
    """A live camera's frame index counts the frames the loop dropped too (``LiveFrame.seq``): a
    100-Hz camera of which every 2nd frame is processed is seen at 50 Hz, so 2/30 s is 3 processed
    frames (3.33 rounded), 6 of the camera's indices; the wait counted in the caller's indices was
    met after 3 of them, every 2nd processed frame: 0.04 s, not 2/30 (fails at a451afe: gap 4)."""
    asked = densify_frames(100.0, 60, stride=2)
    assert len(asked) >= 3, asked
    assert np.diff(asked).min() == 6, asked
