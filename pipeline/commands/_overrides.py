"""Command-line flags shared by ``run`` and ``live``: turned into config overrides (``section.key``), and the
CONFIG argument checked against the repeatable flags."""

from __future__ import annotations

import re
from pathlib import Path


def rig_and_motion_overrides(
    calibration: Path | None,
    trajectory: Path | None,
    speed_mps: float | None,
    out: Path | None,
    sets: list[str] | tuple[str, ...] = (),
) -> dict:
    """Overrides for ``--calibration``, ``--trajectory``, ``--speed-mps`` and ``--out``.

    A calibration file replaces cameras written into the config; a trajectory and a constant speed
    exclude each other, so setting one clears the other's value from the config (a trajectory also
    clears ``ego_motion.t0_s``, which belongs to the constant speed; a constant speed clears
    ``ego_motion.time_offset_s``, which belongs to a trajectory's clock).

    Args:
        sets: the ``--set section.key=value`` items, checked against the flags.

    Raises:
        ConfigError: both ``--trajectory`` and ``--speed-mps`` given (alternatives, not a pair), or one of
            them with a ``--set`` of the other's key (``ego_motion.speed_mps`` or ``ego_motion.t0_s`` /
            ``ego_motion.trajectory``), ``--speed-mps`` with a ``--set`` of ``ego_motion.time_offset_s``,
            or ``--calibration`` with a ``--set`` of ``rig.cameras``: the flag would silently replace it.
    """
    from estimators.errors import ConfigError

    motion = "the body's motion from a TUM file, or a constant forward speed"
    if trajectory is not None and speed_mps is not None:
        raise ConfigError(f"--trajectory {trajectory} and --speed-mps {speed_mps:g} are alternatives "
                          f"({motion}); give one of them, not both")
    for flag, value, key, what in (
        ("--trajectory", trajectory, ("ego_motion", "speed_mps"), motion),
        ("--trajectory", trajectory, ("ego_motion", "t0_s"), motion),
        ("--speed-mps", speed_mps, ("ego_motion", "trajectory"), motion),
        ("--calibration", calibration, ("rig", "cameras"), "the cameras from a calibration file, or inline"),
    ):
        item = _set_of(sets, key) if value is not None else None
        if item is not None:
            shown = f"{value:g}" if isinstance(value, float) else str(value)
            raise ConfigError(f"{flag} {shown} and --set {item} are alternatives ({what}); give one of them, "
                              "not both")
    offset = _set_of(sets, ("ego_motion", "time_offset_s")) if speed_mps is not None else None
    if offset is not None:
        raise ConfigError(f"--set {offset} shifts a trajectory's clock, and --speed-mps {speed_mps:g} "
                          "replaces the trajectory by a constant speed, which has no clock to shift; give "
                          "--trajectory with it, or drop it")
    cli: dict = {}
    if calibration is not None:
        cli["rig.calibration"] = str(calibration)
        cli["rig.cameras"] = None
    if trajectory is not None:
        cli["ego_motion.trajectory"] = str(trajectory)
        cli["ego_motion.speed_mps"] = None
        cli["ego_motion.t0_s"] = 0.0
    if speed_mps is not None:
        cli["ego_motion.speed_mps"] = speed_mps
        cli["ego_motion.trajectory"] = None
        cli["ego_motion.time_offset_s"] = 0.0
    if out is not None:
        cli["outputs.dir"] = str(out)
    return cli


def _set_of(sets: list[str] | tuple[str, ...], key: tuple[str, ...]) -> str | None:
    """The ``--set`` item that gives ``key`` its value (not null), directly or inside its section's
    mapping (``--set ego_motion={speed_mps: 3}``); None when none does or a later item sets it back to
    null. Malformed items are left to load_config."""
    from estimators.errors import ConfigError
    from pipeline.config import _parse_override

    found = None
    for item in sets:
        try:
            parts, value = _parse_override(item)
        except ConfigError:
            continue
        if parts == key[: len(parts)]:
            for p in key[len(parts):]:
                value = value.get(p) if isinstance(value, dict) else None
            found = item if value is not None else None  # a later item replaces an earlier one
    return found


def check_config_argument(config: Path | None, flags: dict[str, list | None]) -> None:
    """Refuse a CONFIG argument that clearly is the second value of a repeatable flag: each such flag
    takes one value (``--video a.mkv b.mkv`` makes b.mkv the CONFIG, ``--camera 0 1`` makes 1 it), so the
    message says to repeat the flag. Clearly: a folder, a file named as a video or an image (there or
    not), or for ``--camera`` a device index. Anything else is left to load_config, which loads it (a YAML
    config of any name) or says what it is: not found (with the presets), or a file that is not a YAML
    config.

    Args:
        flags: the repeatable flags (``--video``, ...) and the values they got.

    Raises:
        ConfigError: ``config`` is such a value and one of ``flags`` got a value.
    """
    from estimators.errors import ConfigError
    from pipeline.sources import IMAGE_SUFFIXES, VIDEO_SUFFIXES

    if config is None:
        return
    # a URL reaches us as a Path, its '//' folded to '/' (rtsp://cam/b -> rtsp:/cam/b): shown unfolded
    text = re.sub(r"^([A-Za-z][A-Za-z0-9+.-]*):/(?!/)", r"\1://", str(config))
    url = text != str(config) or "://" in text
    device = config.exists() and not config.is_file() and not config.is_dir()  # /dev/video1
    media = url or device or config.is_dir() or config.suffix.lower() in (*VIDEO_SUFFIXES, *IMAGE_SUFFIXES)
    for flag, values in flags.items():
        if values and (media or (flag == "--camera" and text.isdigit())):
            raise ConfigError(f"{text}: not a YAML config (the first argument); {flag} takes one value per "
                              f"flag: {flag} {values[-1]} {flag} {text}")
