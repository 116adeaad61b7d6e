"""Command-line flags shared by ``run`` and ``live``, turned into config overrides (``section.key``)."""

from __future__ import annotations

from pathlib import Path


def rig_and_motion_overrides(
    calibration: Path | None, trajectory: Path | None, speed_mps: float | None, out: Path | None
) -> dict:
    """Overrides for ``--calibration``, ``--trajectory``, ``--speed-mps`` and ``--out``.

    A calibration file replaces cameras written into the config; a trajectory and a constant speed
    exclude each other, so setting one clears the other's value from the config.

    Raises:
        ConfigError: both ``--trajectory`` and ``--speed-mps`` given (alternatives, not a pair).
    """
    if trajectory is not None and speed_mps is not None:
        from estimators.errors import ConfigError

        raise ConfigError(
            f"--trajectory {trajectory} and --speed-mps {speed_mps:g} are alternatives (the body's motion "
            "from a TUM file, or a constant forward speed); give one of them, not both"
        )
    cli: dict = {}
    if calibration is not None:
        cli["rig.calibration"] = str(calibration)
        cli["rig.cameras"] = None
    if trajectory is not None:
        cli["ego_motion.trajectory"] = str(trajectory)
        cli["ego_motion.speed_mps"] = None
    if speed_mps is not None:
        cli["ego_motion.speed_mps"] = speed_mps
        cli["ego_motion.trajectory"] = None
    if out is not None:
        cli["outputs.dir"] = str(out)
    return cli
