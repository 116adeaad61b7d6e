"""Sources: video with timestamps sidecar, image folder, stereo sync, bad inputs, paced replay."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from test_run_support import H, W, write_video

from estimators.errors import SourceError
from pipeline.sources import (
    Frame,
    ImageFolderSource,
    PacedSource,
    Source,
    SyncedSource,
    VideoSource,
    open_capture,
    read_timestamps,
)


def test_video_round_trip_with_timestamps_sidecar(tmp_path):
    # dropped frames: the sidecar's frame indices skip 2 and 5; its times are authoritative
    idx = [0, 1, 3, 4, 6, 7]
    times = [0.0, 0.04, 0.121, 0.16, 0.245, 0.28]
    p = write_video(tmp_path / "cam0.mkv", 6, times=times, frames=idx)
    src = VideoSource(p, expected_size=(W, H))
    got = list(src)
    assert [f.frame for f in got] == idx
    assert [f.t_s for f in got] == pytest.approx(times)
    assert [int(f.image[0, 0, 0]) for f in got] == [4 * k for k in range(6)]  # FFV1 is lossless
    assert src.error is None and got[0].camera == "cam0"


def test_video_without_sidecar_uses_container_times(tmp_path):
    p = write_video(tmp_path / "v.mkv", 10, fps=25.0)
    got = list(VideoSource(p))
    assert len(got) == 10
    # Matroska stores milliseconds: 1/25 s = 40 ms exactly
    assert [f.t_s for f in got] == pytest.approx([k / 25.0 for k in range(10)], abs=1e-3)


def test_video_fps_option_gives_frame_over_fps(tmp_path):
    p = write_video(tmp_path / "v.mkv", 4, fps=30.0)
    assert [f.t_s for f in VideoSource(p, fps=10.0)] == pytest.approx([0.0, 0.1, 0.2, 0.3])
    assert VideoSource(p, fps=10.0).frame_times == "inputs.fps" and VideoSource(p).frame_times == "container"


def test_image_folder_sorted_with_fps_and_with_timestamps(tmp_path):
    d = tmp_path / "imgs"
    d.mkdir()
    for k in (2, 0, 1):  # written out of order; read sorted by name
        cv2.imwrite(str(d / f"img_{k:03d}.png"), np.full((H, W), 10 * k, np.uint8))
    got = list(ImageFolderSource(d, fps=20.0, grey=True))
    assert [int(f.image[0, 0]) for f in got] == [0, 10, 20]
    assert [f.t_s for f in got] == pytest.approx([0.0, 0.05, 0.1])
    assert ImageFolderSource(d, fps=20.0).frame_times == "inputs.fps"
    (d / "timestamps.txt").write_text("10 1.5\n11 1.6\n13 1.8\n")
    assert ImageFolderSource(d, fps=20.0).frame_times == str(d / "timestamps.txt")
    got = list(ImageFolderSource(d))
    assert [(f.frame, f.t_s) for f in got] == [(10, 1.5), (11, 1.6), (13, 1.8)]


def test_image_folder_unpadded_names_in_natural_order_with_timestamps(tmp_path):
    """frame_1, frame_2, ..., frame_11 are read 1, 2, ..., 11 (plain name order: 1, 10, 11, 2, ...), and
    the k-th line of timestamps.txt goes with the k-th image in that order."""
    d = tmp_path / "imgs"
    d.mkdir()
    for k in range(1, 12):
        cv2.imwrite(str(d / f"frame_{k}.png"), np.full((H, W), 10 * k, np.uint8))
    (d / "timestamps.txt").write_text("".join(f"{k} {k / 10}\n" for k in range(1, 12)))
    got = list(ImageFolderSource(d, grey=True))
    assert [int(f.image[0, 0]) for f in got] == [10 * k for k in range(1, 12)]
    assert [(f.frame, f.t_s) for f in got] == [(k, pytest.approx(k / 10)) for k in range(1, 12)]


def test_natural_key_keeps_name_order_of_zero_padded_names():
    from pipeline.sources import natural_key

    names = [f"cam0_{k:04d}.png" for k in (0, 7, 10, 99, 100, 1000)] + ["a.png", "b_2.png", "b_10.png"]
    assert sorted(names[:6], key=natural_key) == sorted(names[:6])
    assert sorted(names, key=natural_key) == ["a.png", "b_2.png", "b_10.png"] + names[:6]
    assert sorted(["f_1.png", "f_01.png"], key=natural_key) == ["f_01.png", "f_1.png"]  # a tie: by name


def test_image_folder_without_times_or_images(tmp_path):
    d = tmp_path / "imgs"
    d.mkdir()
    with pytest.raises(SourceError, match="no images"):
        ImageFolderSource(d, fps=10)
    cv2.imwrite(str(d / "a.png"), np.zeros((H, W), np.uint8))
    with pytest.raises(SourceError) as e:  # how to give either: the flag and the two file names
        ImageFolderSource(d)
    assert "give inputs.fps (Hz, e.g. --set inputs.fps=30) or a timestamps file ('frame t_s' per line) " \
           f"{d / 'timestamps.txt'} or {tmp_path / 'imgs.timestamps.txt'}" in str(e.value), str(e.value)


def test_stereo_sync_drops_frame_without_partner(tmp_path):
    t0 = [0.0, 0.1, 0.2, 0.3, 0.4]
    t1 = [0.0, 0.1, 0.3, 0.4]  # cam1 lost the frame at 0.2
    a = write_video(tmp_path / "cam0.mkv", 5, times=t0)
    b = write_video(tmp_path / "cam1.mkv", 4, times=t1)
    sync = SyncedSource([VideoSource(a, "cam0"), VideoSource(b, "cam1")], tolerance_s=0.01)
    sets = list(sync)
    assert [s.t_s for s in sets] == pytest.approx([0.0, 0.1, 0.3, 0.4])
    assert sync.dropped == {"cam0": 1, "cam1": 0}
    for s in sets:
        assert set(s.frames) == {"cam0", "cam1"}
        assert abs(s.frames["cam0"].t_s - s.frames["cam1"].t_s) <= 0.01
    # the pair at 0.3 s: cam0's frame 3 (grey 12) with cam1's frame 2 (grey 8)
    assert int(sets[2].images["cam0"][0, 0, 0]) == 12 and int(sets[2].images["cam1"][0, 0, 0]) == 8


def test_missing_empty_and_corrupt_videos(tmp_path):
    with pytest.raises(SourceError, match=r"nope\.mkv: video file not found"):
        VideoSource(tmp_path / "nope.mkv")
    (tmp_path / "empty.mkv").write_bytes(b"")
    with pytest.raises(SourceError, match=r"empty\.mkv: video file is empty"):
        VideoSource(tmp_path / "empty.mkv")
    # text, not random bytes: FFmpeg's probe sometimes takes 4 KiB of random bytes for a stream
    # (then the error is the next check's, "no frame could be decoded"), which made this test flaky
    (tmp_path / "junk.mkv").write_bytes(b"this is not a video file\n" * 170)
    with pytest.raises(SourceError, match=r"junk\.mkv: cannot be opened"):
        VideoSource(tmp_path / "junk.mkv")
    (tmp_path / "noise.mkv").write_bytes(np.random.default_rng(3).integers(0, 256, 4096, np.uint8).tobytes())
    with pytest.raises(SourceError, match=r"noise\.mkv: (cannot be opened|no frame could be decoded)"):
        VideoSource(tmp_path / "noise.mkv")


def test_truncated_video_keeps_frames_before_the_break(tmp_path):
    p = write_video(tmp_path / "cam0.mkv", 30, times=[k / 30 for k in range(30)])
    data = p.read_bytes()
    cut = tmp_path / "cut.mkv"
    cut.write_bytes(data[: len(data) // 2])
    (tmp_path / "cut.timestamps.txt").write_text((tmp_path / "cam0.timestamps.txt").read_text())
    src = VideoSource(cut)
    got = list(src)
    assert 0 < len(got) < 30
    assert [int(f.image[0, 0, 0]) for f in got] == [4 * k for k in range(len(got))]
    assert src.error is not None and "cut.mkv" in src.error and f"after {len(got)} of 30" in src.error


def test_video_cut_in_header_is_an_error(tmp_path):
    p = write_video(tmp_path / "cam0.mkv", 5)
    cut = tmp_path / "head.mkv"
    cut.write_bytes(p.read_bytes()[:200])
    with pytest.raises(SourceError, match=r"head\.mkv"):
        VideoSource(cut)


def test_frame_size_must_match_calibration(tmp_path):
    p = write_video(tmp_path / "cam0.mkv", 2)
    with pytest.raises(
        SourceError, match=rf"cam0\.mkv: frames are {W}x{H} pixels but the calibration expects 640x480"
    ):
        VideoSource(p, expected_size=(640, 480))


def test_camera_index_that_does_not_exist():
    with pytest.raises(SourceError, match="camera index 97: cannot be opened"):
        open_capture(97)


def test_malformed_timestamps_line(tmp_path):
    f = tmp_path / "t.txt"
    f.write_text("0 0.0\n1 zero\n")
    with pytest.raises(SourceError, match=r"t\.txt:2: expected 'frame t_s'"):
        read_timestamps(f)
    f.write_text("0 0.5\n1 0.4\n")
    with pytest.raises(SourceError, match=r"t\.txt:2: times must increase"):
        read_timestamps(f)


@pytest.mark.parametrize("frames", [[0, 1, 1, 3], [0, 2, 1, 3]], ids=["repeated", "going back"])
def test_timestamps_whose_frame_numbers_do_not_increase(tmp_path, frames):
    f = tmp_path / "t.txt"
    f.write_text("# frame t_s\n" + "".join(f"{k} {0.1 * i:.1f}\n" for i, k in enumerate(frames)))
    with pytest.raises(SourceError, match=rf"t\.txt:4: frame numbers must increase; frame {frames[2]} "
                       rf"follows frame {frames[1]}"):
        read_timestamps(f)


def test_paced_source_releases_frames_at_their_times(tmp_path):
    p = write_video(tmp_path / "cam0.mkv", 4, times=[0.0, 0.5, 1.0, 2.0])
    now = [100.0]
    slept = []

    def sleep(dt):
        slept.append(dt)
        now[0] += dt

    paced = PacedSource(VideoSource(p), speed=2.0, clock=lambda: now[0], sleep=sleep)
    arrivals = []
    for _ in paced:
        arrivals.append(paced.last_arrival_s)
    assert arrivals == pytest.approx([100.0, 100.25, 100.5, 101.0])  # real time / speed


def _grey_video(path, n, fourcc="FFV1", ext_colour=False):
    """An FFV1 single-channel video (the simulator's --grey) of a textured frame that changes per k."""
    yy, xx = np.mgrid[0:H, 0:W]
    w = cv2.VideoWriter(str(path), cv2.CAP_FFMPEG, cv2.VideoWriter_fourcc(*fourcc), 30.0, (W, H), ext_colour)
    assert w.isOpened()
    frames = []
    for k in range(n):
        g = ((xx * 3 + yy * 5 + 17 * k) % 256).astype(np.uint8)
        frames.append(g)
        w.write(cv2.cvtColor(g, cv2.COLOR_GRAY2BGR) if ext_colour else g)
    w.release()
    return frames


def test_grey_video_is_read_natively_frame_exact(tmp_path):
    p = tmp_path / "g.mkv"
    frames = _grey_video(p, 6)
    src = VideoSource(p, grey=True)
    got = list(src)
    assert src.grey_mode == "native"  # no colour conversion at all
    assert len(got) == 6 and all(f.image.shape == (H, W) and f.image.dtype == np.uint8 for f in got)
    for f, want in zip(got, frames, strict=True):
        np.testing.assert_array_equal(f.image, want)  # FFV1 is lossless
    # the same times as the BGR read
    assert [f.t_s for f in got] == [f.t_s for f in VideoSource(p)]


def test_colour_video_read_grey_is_cvtcolor_of_bgr(tmp_path):
    p = tmp_path / "c.mkv"
    yy, xx = np.mgrid[0:H, 0:W]
    w = cv2.VideoWriter(str(p), cv2.CAP_FFMPEG, cv2.VideoWriter_fourcc(*"FFV1"), 30.0, (W, H))
    bgr = [
        np.dstack([(xx + 9 * k) % 256, (yy * 2) % 256, (xx + yy) % 256]).astype(np.uint8) for k in range(4)
    ]
    for im in bgr:
        w.write(im)
    w.release()
    src = VideoSource(p, grey=True)
    got = list(src)
    assert src.grey_mode == "converted" and len(got) == 4
    for f, im in zip(got, bgr, strict=True):
        np.testing.assert_array_equal(f.image, cv2.cvtColor(im, cv2.COLOR_BGR2GRAY))


def test_limited_range_luma_is_not_taken_as_grey(tmp_path):
    """mp4v (yuv420p) hands out its luma plane unconverted: 16..235, not the grey image -> converted."""
    p = tmp_path / "v.mp4"
    _grey_video(p, 3, fourcc="mp4v", ext_colour=True)
    src = VideoSource(p, grey=True)
    got = list(src)
    assert src.grey_mode == "converted" and len(got) == 3 and got[0].image.ndim == 2


class _Counting(VideoSource):
    """A VideoSource that counts the frames it has handed out (to the prefetch thread)."""

    def __iter__(self):
        self.handed = 0
        for f in super().__iter__():
            self.handed += 1
            yield f


def test_prefetch_yields_the_same_frames_and_reads_a_bounded_distance_ahead(tmp_path):
    import time as _time

    from pipeline.sources import PrefetchSource

    p = write_video(tmp_path / "v.mkv", 12)
    want = [(f.frame, f.t_s, int(f.image[0, 0, 0])) for f in VideoSource(p)]
    inner = _Counting(p)
    src = PrefetchSource(inner, depth=2)
    assert src.frame_count == inner.frame_count and src.path == inner.path  # the inner source's
    got = []
    for f in src:
        _time.sleep(0.02)  # a slow consumer: the decoder may run ahead, but only by depth (+1 in hand)
        assert inner.handed <= len(got) + 1 + 2 + 1
        got.append((f.frame, f.t_s, int(f.image[0, 0, 0])))
    assert got == want and src.error is None and not src._thread.is_alive()


def test_prefetch_raises_the_inner_error_in_the_consumer_and_close_stops_the_thread(tmp_path):
    from pipeline.sources import PrefetchSource

    class Broken(Source):
        def __iter__(self):
            yield Frame(0, 0.0, "cam0", np.zeros((2, 2), np.uint8))
            raise SourceError("broken.mkv: bad packet")

    it = iter(PrefetchSource(Broken()))
    assert next(it).frame == 0
    with pytest.raises(SourceError, match="bad packet"):
        next(it)
    p = write_video(tmp_path / "v.mkv", 30)
    src = PrefetchSource(VideoSource(p), depth=1)
    it = iter(src)
    next(it)
    src.close()  # mid-stream: the decoder thread ends before the capture is released
    assert not src._thread.is_alive()
